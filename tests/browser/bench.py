"""Browser HMI benchmark (issue #30; not a test: it prints figures for docs/hmi.md).

- page load on loopback: navigation to load event, and to the first live DRO;
- DRO update rate and latency: when each status snapshot (by its RT `sequence`) reached the
  screen (`cncHmi.drawn`, epoch ms at the animation frame that drew it) against when a native
  gRPC client streaming every tick (250 Hz) first saw that sequence;
- preview of a 1 M-block program: upload through the page (UploadBegin/Part/Finish), select,
  then time from opening the Preview tab to the first picture, and the longest main-thread task
  meanwhile (the page stays responsive when no task is long);
- browser memory (JS heap, DOM nodes) sampled every CNC_SAMPLE_S (60) seconds over CNC_MINUTES
  of live status with a program running, and its slope (MB/h).
Environment: CNC_HMI_URL, CNC_ADDR (gRPC), CNC_TOKEN, CNC_MINUTES, CNC_SAMPLE_S,
CNC_BENCH_PARTS (load,dro,preview,memory), CNC_BENCH_BLOCKS; PYTHONPATH with the stubs."""

import bisect
import os
import statistics
import tempfile
import threading
import time

import grpc
from cnc.v1 import cnc_pb2 as pb
from cnc.v1 import cnc_pb2_grpc as rpc
from selenium.webdriver.common.by import By

from chromium import browser

URL = os.environ["CNC_HMI_URL"]
TOKEN = os.environ["CNC_TOKEN"]
MINUTES = float(os.environ.get("CNC_MINUTES", "10"))
META = (("authorization", f"Bearer {TOKEN}"),)
channel = grpc.insecure_channel(os.environ["CNC_ADDR"])
machine = rpc.MachineStub(channel)


def wait(what, cond, timeout=600):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            v = cond()
            if v:
                return v
        except Exception:
            pass
        time.sleep(0.02)
    raise AssertionError(f"timed out: {what}")


def tid(d, name):
    return d.find_element(By.CSS_SELECTOR, f'[data-testid="{name}"]')


def page_load(d) -> None:
    loads, lives = [], []
    for _ in range(5):
        d.get("about:blank")
        t0 = time.time() * 1000
        d.get(URL)
        wait("live", lambda: tid(d, "connection-state").text == "connected")
        t_live = time.time() * 1000
        nav = d.execute_script("const n = performance.getEntriesByType('navigation')[0];"
                               "return [n.loadEventEnd, n.transferSize + 0];")
        loads.append(nav[0])
        lives.append(t_live - t0)
    size = d.execute_script("return performance.getEntriesByType('resource')"
                            ".filter(r => /app\\.(js|css)/.test(r.name))"
                            ".reduce((a, r) => a + r.encodedBodySize, 0)")
    print(f"page load: load event {statistics.median(loads):.0f} ms, first live DRO "
          f"{statistics.median(lives):.0f} ms (median of 5; app.js + app.css {size / 1024:.0f} KiB)")


class Native:
    """First arrival time (epoch ms) of every status sequence at a native client, 250 Hz."""

    def __init__(self):
        self.seen: dict[int, float] = {}
        self.stream = machine.StreamStatus(pb.StatusRequest(rate_hz=250), metadata=META)
        threading.Thread(target=self.run, daemon=True).start()

    def run(self):
        try:
            for s in self.stream:
                self.seen.setdefault(s.sequence, time.time() * 1000)
        except grpc.RpcError:
            pass


def start_loop_program():
    text = "".join(f"N{10 * (i + 1)} G1 X{(i % 2) * 100} Y{(i // 2 % 2) * 50} F6000\n" for i in range(400))
    machine.LoadProgram(pb.LoadProgramRequest(name="bench_loop.nc", text=text), metadata=META)
    machine.Start(pb.StartRequest(), metadata=META)


def dro_rate_and_latency(d, seconds=20.0) -> None:
    native = Native()
    start_loop_program()
    d.execute_script("cncHmi.drawn.length = 0")
    time.sleep(seconds)
    drawn = d.execute_script("return cncHmi.drawn.slice()")
    native.stream.cancel()
    seqs = sorted(native.seen)
    lat = []
    for seq, t in drawn:
        i = bisect.bisect_left(seqs, seq)
        if i < len(seqs):
            lat.append(t - native.seen[seqs[i]])
    span_s = (drawn[-1][1] - drawn[0][1]) / 1000
    distinct = len({s for s, _ in drawn})
    lat.sort()
    print(f"DRO: {distinct / span_s:.1f} updates/s over {span_s:.0f} s (status stream asked at 30 Hz); "
          f"latency RT snapshot -> screen: median {statistics.median(lat):.0f} ms, "
          f"p95 {lat[int(0.95 * len(lat))]:.0f} ms, max {lat[-1]:.0f} ms ({len(lat)} updates)")
    machine.Stop(pb.StopRequest(), metadata=META)


def big_program(path: str, blocks: int) -> None:
    with open(path, "w") as f:
        f.write("N1 G0 X0 Y0\n")
        for i in range(1, blocks):
            # A CAM-like raster of short moves with a small wiggle (junctions of every kind).
            row, col = divmod(i, 1000)
            x = col * 0.1 if row % 2 == 0 else (999 - col) * 0.1
            y = row * 0.1 + (0.02 if col % 7 == 0 else 0)
            f.write(f"G1 X{x:.3f} Y{y:.3f} F3000\n")


def preview_big(d, blocks: int) -> None:
    path = os.path.join(tempfile.mkdtemp(), f"cam_{blocks}.nc")
    big_program(path, blocks)
    size_mb = os.path.getsize(path) / 1e6
    d.get(URL + "#token=" + TOKEN)
    wait("operator", lambda: tid(d, "role").get_attribute("textContent") == "operator")
    tid(d, "tab-programs").click()
    t0 = time.time()
    tid(d, "program-upload").send_keys(path)
    wait("stored", lambda: d.find_elements(By.CSS_SELECTOR, f'tr[data-name="cam_{blocks}.nc"]'))
    t_up = time.time() - t0
    d.find_element(By.CSS_SELECTOR, f'tr[data-name="cam_{blocks}.nc"]').click()
    t0 = time.time()
    tid(d, "program-select").click()
    wait("selected", lambda: tid(d, "program-name").get_attribute("textContent") == f"cam_{blocks}.nc")
    t_sel = time.time() - t0
    d.execute_script("""window.__long = 0; new PerformanceObserver((l) => { for (const e of l.getEntries())
        window.__long = Math.max(window.__long, e.duration); }).observe({type: 'longtask', buffered: false});""")
    t0 = time.time()
    tid(d, "tab-preview").click()
    wait("drawn", lambda: tid(d, "preview").get_attribute("data-state") == "drawn"
         and f"cam_{blocks}.nc" in tid(d, "preview-info").get_attribute("textContent"))
    t_pic = time.time() - t0
    mode = tid(d, "preview").get_attribute("data-mode")
    # Responsiveness: a click on another tab is handled at once after the picture.
    t0 = time.time()
    tid(d, "tab-run").click()
    wait("run shown", lambda: tid(d, "run-listing").is_displayed())
    t_click = time.time() - t0
    long_ms = d.execute_script("return window.__long")
    print(f"preview {blocks} blocks ({size_mb:.0f} MB): upload {t_up:.1f} s, select {t_sel:.1f} s, "
          f"first picture {t_pic:.2f} s ({mode}), longest main-thread task {long_ms:.0f} ms, "
          f"tab switch after it {t_click * 1000:.0f} ms")


def slope_mb_per_h(samples) -> float:
    """Least-squares slope of (minute, MB) samples, in MB per hour."""
    n = len(samples)
    mx = sum(t for t, _ in samples) / n
    my = sum(v for _, v in samples) / n
    sxx = sum((t - mx) ** 2 for t, _ in samples)
    return 60 * sum((t - mx) * (v - my) for t, v in samples) / sxx if sxx else 0.0


def memory_run(d, minutes: float) -> None:
    """JS heap and DOM nodes (after a forced garbage collection, via CDP Performance.getMetrics)
    every CNC_SAMPLE_S seconds over MINUTES of live status with a program running on the Run
    screen; the slope is fitted after the first two minutes (warm-up). The latency probe's ring
    (cncHmi.drawn, a benchmark aid of at most 20,000 frames) is emptied before each sample so it
    does not count as the page's own growth."""
    every_s = float(os.environ.get("CNC_SAMPLE_S", "60"))
    d.get(URL)
    wait("live", lambda: tid(d, "connection-state").text == "connected")
    d.execute_cdp_cmd("Performance.enable", {})

    def metrics():
        d.execute_script("cncHmi.drawn.length = 0")
        d.execute_cdp_cmd("HeapProfiler.collectGarbage", {})
        m = {x["name"]: x["value"] for x in d.execute_cdp_cmd("Performance.getMetrics", {})["metrics"]}
        return m["JSHeapUsedSize"] / 1e6, int(m["Nodes"])
    start_loop_program()
    t_start = time.time()
    heap0, nodes0 = metrics()
    samples = [(0.0, heap0, nodes0)]
    end = t_start + minutes * 60
    next_sample = t_start + every_s
    while time.time() < end:
        time.sleep(min(10, max(0.1, end - time.time())))
        st = machine.StreamStatus(pb.StatusRequest(rate_hz=1), metadata=META)
        s = next(st)
        st.cancel()
        if s.state == pb.MACHINE_STATE_IDLE:
            machine.Start(pb.StartRequest(), metadata=META)
        if time.time() >= next_sample or time.time() >= end:
            next_sample += every_s
            heap, nodes = metrics()
            t_min = (time.time() - t_start) / 60
            samples.append((t_min, heap, nodes))
            print(f"memory sample {t_min:6.1f} min: JS heap {heap:.2f} MB, DOM nodes {nodes}", flush=True)
    heap1, nodes1 = samples[-1][1], samples[-1][2]
    steady = [(t, h) for t, h, _ in samples if t >= 2] or [(t, h) for t, h, _ in samples]
    peak = max(h for _, h, _ in samples)
    print(f"memory after {samples[-1][0]:.0f} min of live status (program running, 30 Hz): JS heap "
          f"{heap0:.1f} -> {heap1:.1f} MB (peak {peak:.1f}), slope after 2 min "
          f"{slope_mb_per_h(steady):+.2f} MB/h over {len(steady)} samples, DOM nodes {nodes0} -> {nodes1}",
          flush=True)
    machine.Stop(pb.StopRequest(), metadata=META)


# CNC_BENCH_PARTS picks the parts (e.g. "memory" alone for a long memory run).
PARTS = os.environ.get("CNC_BENCH_PARTS", "load,dro,preview,memory").split(",")
d = browser()
if "load" in PARTS:
    page_load(d)
if "dro" in PARTS:
    dro_rate_and_latency(d)
if "preview" in PARTS:
    for n in os.environ.get("CNC_BENCH_BLOCKS", "50000,1000000").split(","):
        preview_big(d, int(n))
if "memory" in PARTS:
    memory_run(d, MINUTES)
d.quit()
