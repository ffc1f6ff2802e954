// How numbers and states read on the screen.
import { Code, ConnectError } from "@connectrpc/connect";
import { MachineState } from "./gen/cnc/v1/cnc_pb";

export function mm(v: number): string {
  return v.toFixed(3);
}

export function stateName(s: MachineState): string {
  switch (s) {
    case MachineState.IDLE:
      return "IDLE";
    case MachineState.RUNNING:
      return "RUNNING";
    case MachineState.STOPPING:
      return "STOPPING";
    case MachineState.HOLD:
      return "HOLD";
    case MachineState.FAULT:
      return "FAULT";
    case MachineState.ENABLING:
      return "ENABLING";
    case MachineState.SHUTDOWN:
      return "SHUTDOWN";
    case MachineState.JOG:
      return "JOG";
    case MachineState.HOMING:
      return "HOMING";
    default:
      return "—";
  }
}

/** A refusal as the operator reads it: the status code name and the server's message. */
export function errorText(e: unknown): string {
  if (e instanceof ConnectError) return `${Code[e.code]}: ${e.rawMessage}`;
  return String(e);
}

export function time(unixMs: bigint | number): string {
  const d = new Date(Number(unixMs));
  return d.toLocaleString();
}
