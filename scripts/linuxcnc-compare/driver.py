#!/usr/bin/python3
"""The 'display' of the headless LinuxCNC run (started by the linuxcnc launcher from the INI's
[DISPLAY] DISPLAY): homes the simulated machine, runs each program, and records the servo
thread's commanded positions with halsampler into <out>/<name>.samples.

Usage (by the launcher): driver.py <programs dir> <out dir> [names...] -ini <file>
"""

import os
import subprocess
import sys
import time

import linuxcnc


def wait(pred, timeout, what):
    t0 = time.time()
    while time.time() - t0 < timeout:
        if pred():
            return
        time.sleep(0.01)
    raise TimeoutError(what)


def main():
    args = [a for a in sys.argv[1:]]
    if "-ini" in args:
        k = args.index("-ini")
        del args[k : k + 2]
    args = [a for a in args if a != "--"]
    prog_dir, out_dir, names = args[0], args[1], args[2:]
    s = linuxcnc.stat()
    c = linuxcnc.command()
    err = linuxcnc.error_channel()

    def poll():
        s.poll()
        return s

    wait(lambda: poll() is not None, 30, "task")
    c.state(linuxcnc.STATE_ESTOP_RESET)
    c.wait_complete()
    c.state(linuxcnc.STATE_ON)
    c.wait_complete()
    c.mode(linuxcnc.MODE_MANUAL)
    c.wait_complete()
    c.home(-1)
    c.wait_complete()
    wait(lambda: all(poll().homed[:3]), 30, "homing")
    c.teleop_enable(1)
    c.wait_complete()
    log = open(os.path.join(out_dir, "driver.log"), "w")
    for name in names:
        path = os.path.abspath(os.path.join(prog_dir, f"{name}.ngc"))
        c.mode(linuxcnc.MODE_AUTO)
        c.wait_complete()
        samples = open(os.path.join(out_dir, f"{name}.samples"), "w")
        sampler = subprocess.Popen(["stdbuf", "-oL", "halsampler", "-c", "0"], stdout=samples)
        time.sleep(0.5)
        c.program_open(path)
        c.wait_complete()
        t0 = time.time()
        c.auto(linuxcnc.AUTO_RUN, 0)
        wait(lambda: poll().exec_state != linuxcnc.EXEC_DONE or s.queue > 0, 60, "start")
        wait(
            lambda: poll().interp_state == linuxcnc.INTERP_IDLE and s.queue == 0 and s.inpos,
            1800,
            f"program {name}",
        )
        time.sleep(0.5)
        sampler.terminate()
        sampler.wait()
        samples.close()
        e = err.poll()
        log.write(f"{name}: wall {time.time() - t0:.1f} s, error {e}\n")
        log.flush()
        # back to the origin for the next program
        c.mode(linuxcnc.MODE_MDI)
        c.wait_complete()
        c.mdi("G0 X0 Y0 Z0")
        c.wait_complete()
        wait(lambda: poll().interp_state == linuxcnc.INTERP_IDLE and s.queue == 0 and s.inpos, 120, "return")
    c.state(linuxcnc.STATE_OFF)
    c.wait_complete()
    log.close()


if __name__ == "__main__":
    main()
