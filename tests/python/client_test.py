"""A client in another language: Python grpcio with stubs generated from proto/ (issue #8).

Runs a program to its end, edits an offset and reads it back, reads AKRR cells, and checks
the role boundary and a validation error. Prints "N passed, M failed" last; exit status 1 on
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

