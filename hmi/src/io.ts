// What the machine's inputs and outputs say that an operator must see at once (docs/io.md):
// the e-stop chain, the door, a limit switch, outputs forced for commissioning. The I/O screen
// shows them as its banner and the Run screen as a compact strip, from the same list.
import type { IoList } from "./gen/cnc/v1/cnc_pb";
import { t } from "./i18n";

export type IoWarning = { kind: "estop" | "door" | "limit" | "forced"; text: string };

export function ioWarnings(io: IoList | undefined): IoWarning[] {
  if (!io) return [];
  const w: IoWarning[] = [];
  if (io.estopOpen) w.push({ kind: "estop", text: t("io.estop") });
  if (io.doorOpen) w.push({ kind: "door", text: t("io.door") });
  if (io.limitReached) {
    const at = io.inputs.filter((p) => p.function.startsWith("limit_") && p.value).map((p) => p.name);
    w.push({ kind: "limit", text: at.length ? t("io.limitAt", { names: at.join(", ") }) : t("io.limit") });
  }
  const forced = io.outputs.filter((p) => p.forced).map((p) => `${p.name}=${p.value ? 1 : 0}`);
  if (forced.length) w.push({ kind: "forced", text: t("io.forced", { list: forced.join(", ") }) });
  return w;
}

/** A key that changes exactly when the warnings do (the strips are redrawn only then). */
export function warningsKey(w: IoWarning[]): string {
  return w.map((x) => x.text).join("|");
}
