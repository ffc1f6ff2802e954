// How numbers and states read on the screen.
import { MachineState } from "./gen/cnc/v1/cnc_pb";
import { lang, t } from "./i18n";

export { errorText } from "./server_text";

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

/** The machine state as the operator reads it (stateName stays the stable English code:
 * `data-state` and the tests match it). */
export function stateLabel(s: MachineState): string {
  const n = stateName(s);
  return n === "—" ? n : t(`state.${n}` as Parameters<typeof t>[0]);
}

export function time(unixMs: bigint | number): string {
  const d = new Date(Number(unixMs));
  return d.toLocaleString(lang() === "cs" ? "cs-CZ" : "en-GB");
}
