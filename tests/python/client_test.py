"""A client in another language: Python grpcio with stubs generated from proto/ (issue #8).

Runs a program to its end, edits an offset and reads it back, reads AKRR cells, and checks
the role boundary and a validation error; the library upload in chunks, reflection v1alpha,
distance to go, spindle and rapid override, homed and soft-limit state (issue #19). Prints "N passed, M failed" last; exit status 1 on
any failure. Environment: CNC_ADDR (host:port), CNC_TOKEN (an operator token).
"""

import os
import sys
import time
import traceback

import grpc

from cnc.v1 import cnc_pb2 as pb
from cnc.v1 import cnc_pb2_grpc as rpc

ADDR = os.environ["CNC_ADDR"]
TOKEN = os.environ["CNC_TOKEN"]
AUTH = (("authorization", "Bearer " + TOKEN),)

PROGRAM = """N10 G0 X10 Y5
N20 G1 X30 F3000
N30 Y20 Z-2
N40 G0 X12.5 Y7.25 Z1
"""

channel = grpc.insecure_channel(ADDR)
machine = rpc.MachineStub(channel)
offsets = rpc.OffsetsStub(channel)
plc = rpc.PlcStub(channel)
programs = rpc.ProgramsStub(channel)

TESTS = []


def test(fn):
    TESTS.append(fn)
    return fn


def wait_for_daemon():
    deadline = time.time() + 60
    while True:
        try:
            grpc.channel_ready_future(channel).result(timeout=2)
            s = next(iter(machine.StreamStatus(pb.StatusRequest(rate_hz=25), timeout=5)))
            if s.state == pb.MACHINE_STATE_IDLE:
                return
        except (grpc.FutureTimeoutError, grpc.RpcError):
            pass
        if time.time() > deadline:
            raise RuntimeError(f"cncd at {ADDR} did not become idle")
        time.sleep(0.2)


def wait_idle():
    deadline = time.time() + 60
    for s in machine.StreamStatus(pb.StatusRequest(rate_hz=25), timeout=90):
        if s.state == pb.MACHINE_STATE_IDLE:
            return
        assert time.time() < deadline, "machine not idle"


@test
def health_is_serving():
    check = channel.unary_unary(
        "/grpc.health.v1.Health/Check",
        request_serializer=lambda b: b,
        response_deserializer=lambda b: b,
    )
    # HealthCheckRequest{service: ""} is empty; HealthCheckResponse{status: SERVING} = 08 01.
    assert check(b"", timeout=5) == b"\x08\x01"


@test
def run_program_to_its_end():
    machine.LoadProgram(pb.LoadProgramRequest(name="py.nc", text=PROGRAM), metadata=AUTH)
    job = machine.Start(pb.StartRequest(), metadata=AUTH).job
    deadline = time.time() + 60
    saw_running = False
    for s in machine.StreamStatus(pb.StatusRequest(rate_hz=50), timeout=90):
        saw_running |= s.state == pb.MACHINE_STATE_RUNNING and s.job == job
        if s.finished_job == job:
            assert s.percent == 100.0, s.percent
            pos = {a.name: a.commanded_mm for a in s.axes}
            assert abs(pos["X"] - 12.5) < 1e-6 and abs(pos["Y"] - 7.25) < 1e-6, pos
            assert abs(pos["Z"] - 1.0) < 1e-6, pos
            break
        assert s.aborted_job != job, "job aborted"
        assert time.time() < deadline, "program did not finish"
    assert saw_running


@test
def edit_an_offset_and_read_it_back():
    e = offsets.SetOffset(
        pb.SetOffsetRequest(entry=5, radius_mm=1.25, length3_mm=-42.5), metadata=AUTH
    )
    assert e.radius_mm == 1.25
    table = offsets.GetOffsets(pb.GetOffsetsRequest())
    e5 = [e for e in table.entries if e.entry == 5][0]
    assert e5.radius_mm == 1.25 and list(e5.length_mm) == [0.0, 0.0, -42.5, 0.0], e5
    assert not e5.changed_by_program
    text = offsets.GetOffsetsFile(pb.GetOffsetsFileRequest()).text
    assert "05: R=1.25" in text, text


@test
def read_akrr_cells():
    cells = plc.ListCells(pb.ListCellsRequest()).cells
    names = {c.name: c for c in cells}
    for n in ["AKRR_ACT_V", "AKRR_ACT_S", "AKRR_V", "AKRR_CNTR", "DYNAM_SET"]:
        assert n in names, n
    assert names["AKRR_ACT_V"].unit == "mm/min"
    assert names["AKRR_ACT_V"].address == 0xA178
    assert names["AKRR_ACT_S"].access == pb.CELL_ACCESS_READ_ONLY
    plc.WriteCell(
        pb.WriteCellRequest(cell=pb.CellRef(name="AKRR_V"), value=120000), metadata=AUTH
    )
    r = plc.ReadCells(
        pb.ReadCellsRequest(cells=[pb.CellRef(name="AKRR_V"), pb.CellRef(address=0xA194)])
    ).cells
    assert (r[0].name, r[0].value, r[0].unit) == ("AKRR_V", 120000, "mm/min"), r[0]
    assert r[1].name == "AKRR_ACT_S" and r[1].unit == "1/1000 rpm", r[1]


@test
def refusals_carry_the_right_codes():
    try:
        plc.WriteCell(pb.WriteCellRequest(cell=pb.CellRef(name="DYNAM_SET"), value=1))
        raise AssertionError("write without a token was accepted")
    except grpc.RpcError as e:
        assert e.code() == grpc.StatusCode.PERMISSION_DENIED, e
    try:
        machine.ListPrograms(pb.ListProgramsRequest(), metadata=(("authorization", "Bearer x"),))
        raise AssertionError("unknown token accepted")
    except grpc.RpcError as e:
        assert e.code() == grpc.StatusCode.UNAUTHENTICATED, e
    try:
        plc.WriteCell(
            pb.WriteCellRequest(cell=pb.CellRef(name="DYNAM_SET"), value=9), metadata=AUTH
        )
        raise AssertionError("out-of-range write accepted")
    except grpc.RpcError as e:
        assert e.code() == grpc.StatusCode.INVALID_ARGUMENT, e


@test
def validation_reports_blocks_and_lines():
    r = machine.ValidateProgram(pb.ValidateProgramRequest(text="N10 G1 X1 F100\nN20 G7\n"))
    assert not r.valid
    errors = [d for d in r.diagnostics if d.severity == pb.SEVERITY_ERROR]
    assert errors and errors[0].block == 20 and errors[0].line == 2, errors


@test
def reflection_v1alpha_lists_the_services():
    # grpcio-reflection and many tools speak only v1alpha; a raw call keeps the test free of
    # that package: ServerReflectionRequest { list_services: "" } is field 7, empty.
    info = channel.stream_stream(
        "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
        request_serializer=lambda b: b,
        response_deserializer=lambda b: b,
    )
    answer = next(iter(info(iter([b"\x3a\x00"]), timeout=10)))
    for name in [b"cnc.v1.Machine", b"cnc.v1.Programs", b"grpc.health.v1.Health"]:
        assert name in answer, answer


@test
def upload_in_chunks_list_and_download():
    text = PROGRAM.encode()

    def chunks():
        yield pb.ProgramChunk(name="chunked.nc", data=text[:10], total_bytes=len(text))
        yield pb.ProgramChunk(data=text[10:])

    replies = list(programs.Upload(chunks(), metadata=AUTH, timeout=60))
    done = replies[-1].done
    assert done.program.name == "chunked.nc", done
    assert done.program.blocks == 4 and done.program.valid, done
    assert done.program.size_bytes == len(text), done
    lib = programs.List(pb.LibraryListRequest())
    assert "chunked.nc" in [p.name for p in lib.programs], lib
    back = b"".join(
        c.data for c in programs.Download(pb.ProgramName(name="chunked.nc"), timeout=30)
    )
    assert back == text, back


@test
def distance_to_go_while_moving():
    job = machine.Mdi(pb.MdiRequest(block="G1 X60 F900"), metadata=AUTH).job
    checked = False
    deadline = time.time() + 60
    for s in machine.StreamStatus(pb.StatusRequest(rate_hz=50), timeout=90):
        x = [a for a in s.axes if a.name == "X"][0]
        if s.job == job and s.state == pb.MACHINE_STATE_RUNNING and x.distance_to_go_mm > 1.0:
            assert abs(60.0 - x.commanded_mm - x.distance_to_go_mm) < 1e-6, x
            checked = True
            break
        assert time.time() < deadline, "never saw the move"
    machine.Stop(pb.StopRequest(), metadata=AUTH)
    assert checked


@test
def spindle_and_rapid_override_homed_and_soft_limits():
    machine.SetSpindleOverride(pb.SetSpindleOverrideRequest(percent=80), metadata=AUTH)
    machine.SetRapidOverride(pb.SetRapidOverrideRequest(percent=25), metadata=AUTH)
    for call, pct in ((machine.SetSpindleOverride, 130), (machine.SetRapidOverride, 101)):
        req = (pb.SetSpindleOverrideRequest if call == machine.SetSpindleOverride
               else pb.SetRapidOverrideRequest)(percent=pct)
        try:
            call(req, metadata=AUTH)
            raise AssertionError(f"{pct} % accepted")
        except grpc.RpcError as e:
            assert e.code() == grpc.StatusCode.INVALID_ARGUMENT, e
    # S1000 at 80 %: the spindle runs at 800 rpm.
    wait_idle()
    machine.Mdi(pb.MdiRequest(block="S1000 M3"), metadata=AUTH)
    deadline = time.time() + 60
    for s in machine.StreamStatus(pb.StatusRequest(rate_hz=25), timeout=90):
        if s.spindle_override_percent == 80 and abs(s.spindle_rpm - 800.0) < 1.0:
            assert s.rapid_override_percent == 25, s
            for a in s.axes:
                # No reference run configured: every axis counts as homed; no soft limits.
                assert a.homed and not a.homing_required, a
                assert a.at_soft_limit == 0 and not a.HasField("soft_max_mm"), a
            break
        assert time.time() < deadline, f"spindle at {s.spindle_rpm} rpm"
    wait_idle()
    machine.Mdi(pb.MdiRequest(block="M5"), metadata=AUTH)
    machine.SetSpindleOverride(pb.SetSpindleOverrideRequest(percent=100), metadata=AUTH)
    machine.SetRapidOverride(pb.SetRapidOverrideRequest(percent=100), metadata=AUTH)


def main():
    try:
        wait_for_daemon()
    except Exception:  # noqa: BLE001
        traceback.print_exc()
        print(f"0 passed, {len(TESTS)} failed")
        return 1
    passed = failed = 0
    for fn in TESTS:
        try:
            fn()
            passed += 1
            print(f"ok    {fn.__name__}")
        except Exception:  # noqa: BLE001 - report every failure and go on
            failed += 1
            print(f"FAIL  {fn.__name__}")
            traceback.print_exc()
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

