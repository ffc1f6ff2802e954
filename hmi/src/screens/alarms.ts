// Alarms: the active alarms (from the status stream: always current) and the history of
// raised and cleared alarms (StreamAlarms, reopened when the connection comes back).
import { machine } from "../api";
import { button, fill, h } from "../dom";
import { errorText, time } from "../format";
import { t } from "../i18n";
import { alarmSource, alarmText } from "../server_text";
import { type Screen, messageLine } from "../screen";
import { onConnection, subscribe } from "../status";
import type { AlarmEvent } from "../gen/cnc/v1/cnc_pb";

const HISTORY_KEEP = 500;

export function alarmsScreen(): Screen {
  const msg = messageLine();
  const active = h("ul", { class: "alarms", testid: "alarm-list" });
  const history = h("ul", { class: "alarms history", testid: "alarm-history" });
  const events: AlarmEvent[] = [];
  let key = "";

  subscribe((s) => {
    const k = s.activeAlarms.map((a) => a.id).join(",");
    if (k === key) return;
    key = k;
    fill(active, ...s.activeAlarms.map((a) =>
      h("li", { class: "alarm active", "data-id": String(a.id), "data-source": a.source },
        h("span", { class: "when" }, time(a.raisedUnixMs)), ` ${alarmSource(a.source)}: ${alarmText(a.message)}`)));
  });

  function drawHistory(): void {
    fill(history, ...events.slice().reverse().map((e) =>
      h("li", { class: e.active ? "alarm raised" : "alarm cleared" },
        h("span", { class: "when" }, time(e.eventUnixMs)), ` ${t(e.active ? "alarms.raised" : "alarms.cleared")} #${e.alarm?.id}: ${alarmText(e.alarm?.message ?? "")}`)));
  }

  let open = false;
  async function follow(): Promise<void> {
    if (open) return;
    open = true;
    events.length = 0;
    try {
      for await (const e of machine.streamAlarms({ skipHistory: false })) {
        events.push(e);
        if (events.length > HISTORY_KEEP) events.shift();
        drawHistory();
      }
    } catch {
      // Reopened when the status stream is live again.
    }
    open = false;
  }
  onConnection((c) => c === "live" && void follow());

  const el = h("div", { class: "screen alarms-screen" },
    h("div", { class: "row" }, h("h3", {}, t("alarms.active")), button(t("alarms.reset"), "alarm-reset", () =>
      machine.reset({}).then(() => msg.ok(t("alarms.resetDone")), (e) => msg.err(errorText(e))), "reset")),
    active, msg.el, h("h3", {}, t("alarms.history")), history);
  return { id: "alarms", el };
}
