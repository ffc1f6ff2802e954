// The daemon's texts in the screen's language. The daemon writes English; what it says is
// recognised by its stable codes (diagnostic codes, gRPC status codes) or, for alarms, by
// the fixed sentences it writes. In English the server's text is shown as it came.
import { Code, ConnectError, decodeBinaryHeader } from "@connectrpc/connect";
import { DIAGNOSTICS_HEADER } from "./api";
import { type Diagnostic, DiagnosticsSchema } from "./gen/cnc/v1/cnc_pb";
import { lang } from "./i18n";
import { alarmCs, alarmSourceCs } from "./lang/alarms_cs";
import { diagnosticsCs } from "./lang/diagnostics_cs";

/** gRPC status codes as a Czech operator reads them. */
const CODES_CS: Partial<Record<Code, string>> = {
  [Code.Canceled]: "Zrušeno",
  [Code.Unknown]: "Neznámá chyba",
  [Code.InvalidArgument]: "Chybné zadání",
  [Code.DeadlineExceeded]: "Vypršel čas",
  [Code.NotFound]: "Nenalezeno",
  [Code.AlreadyExists]: "Již existuje",
  [Code.PermissionDenied]: "Nedostatečné oprávnění",
  [Code.ResourceExhausted]: "Vyčerpáno",
  [Code.FailedPrecondition]: "Nelze v tomto stavu",
  [Code.Aborted]: "Přerušeno",
  [Code.OutOfRange]: "Mimo rozsah",
  [Code.Unimplemented]: "Nepodporováno",
  [Code.Internal]: "Vnitřní chyba",
  [Code.Unavailable]: "Nedostupné",
  [Code.DataLoss]: "Ztráta dat",
  [Code.Unauthenticated]: "Nepřihlášen",
};

/** The coded diagnostics of a refusal (INVALID_ARGUMENT carries every error with its line;
 * other refusals may carry the one code that says why). */
export function diagnosticsOf(e: unknown): Diagnostic[] {
  const v = e instanceof ConnectError ? e.metadata.get(DIAGNOSTICS_HEADER) : null;
  if (!v) return [];
  try {
    return decodeBinaryHeader(v, DiagnosticsSchema).items;
  } catch {
    return [];
  }
}

/** A diagnostic's text: Czech by its code, or the server's message. */
export function diagText(code: string, message: string): string {
  return lang() === "cs" ? (diagnosticsCs[code] ?? message) : message;
}

/** A text of the server that may carry a `[code]` or start with `code:`: Czech by that code. */
export function serverText(message: string): string {
  if (lang() !== "cs") return message;
  const m = /\[([a-z][a-z0-9_]*)\]/.exec(message) ?? /^([a-z][a-z0-9_]*):/.exec(message);
  if (m && diagnosticsCs[m[1]]) {
    const line = /line (\d+)/.exec(message);
    return `[${m[1]}] ${diagnosticsCs[m[1]]}${line ? ` (řádek ${line[1]})` : ""}`;
  }
  return alarmCs(message);
}

/** A refusal as the operator reads it: the status code and the server's message (in Czech:
 * the status in words and the diagnostics' texts by their codes). */
export function errorText(e: unknown): string {
  if (!(e instanceof ConnectError)) return String(e);
  if (lang() !== "cs") return `${Code[e.code]}: ${e.rawMessage}`;
  const diags = diagnosticsOf(e);
  const why = diags.length
    ? diags.slice(0, 3).map((d) => `[${d.code}] ${diagText(d.code, d.message)}`).join("; ")
    : serverText(e.rawMessage);
  return `${CODES_CS[e.code] ?? Code[e.code]}: ${why}`;
}

export function alarmText(message: string): string {
  return lang() === "cs" ? serverText(message) : message;
}

export function alarmSource(source: string): string {
  return lang() === "cs" ? alarmSourceCs(source) : source;
}
