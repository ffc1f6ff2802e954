// The DRO beside every screen: per axis the commanded position (big; the diameter on a
// lathe's X), the actual position and the distance to go. Greyed out, with "NOT LIVE", as
// soon as the status stream stalls or drops.
import type { AxisStatus, Status } from "./gen/cnc/v1/cnc_pb";
import { h, setText } from "./dom";
import { mm } from "./format";
import { t } from "./i18n";
import { onConnection, subscribe } from "./status";

interface Row {
  cmd: HTMLElement;
  act: HTMLElement;
  dtg: HTMLElement;
  label: HTMLElement;
  row: HTMLElement;
}

export function droPanel(): HTMLElement {
  const rows = new Map<string, Row>();
  const list = h("div", { class: "dro-rows" });
  const speed = h("span", {}, "—");
  const stale = h("div", { class: "stale-banner" }, t("dro.notLive"));
  const panel = h(
    "aside",
    { class: "dro stale" },
    stale,
    list,
    h("div", { class: "dro-foot" }, `${t("dro.pathSpeed")} `, speed, ` ${t("unit.mmMin")}`),
  );

  function row(a: AxisStatus): Row {
    let r = rows.get(a.name);
    if (r) return r;
    const label = h("span", { class: "axis" }, a.name);
    const cmd = h("span", { class: "cmd", testid: `dro-${a.name}` }, "");
    const act = h("span", {}, "");
    const dtg = h("span", {}, "");
    const el = h(
      "div",
      { class: "dro-row" },
      h("div", { class: "dro-main" }, label, cmd),
      h("div", { class: "dro-sub" }, h("span", {}, `${t("dro.actual")} `), act, h("span", {}, `  ${t("dro.toGo")} `), dtg),
    );
    list.append(el);
    r = { cmd, act, dtg, label, row: el };
    rows.set(a.name, r);
    return r;
  }

  subscribe((s: Status) => {
    for (const a of s.axes) {
      const r = row(a);
      // display_mm: the commanded position in program units (diameter on a diameter axis).
      setText(r.cmd, mm(a.diameter ? a.displayMm : a.commandedMm));
      setText(r.label, a.diameter ? `${a.name} Ø` : a.name);
      setText(r.act, mm(a.diameter ? 2 * a.actualMm : a.actualMm));
      setText(r.dtg, mm(a.distanceToGoMm));
      r.row.classList.toggle("unhomed", a.homingRequired && !a.homed);
      r.row.classList.toggle("at-limit", a.atSoftLimit !== 0);
      r.cmd.dataset.seq = String(s.sequence);
    }
    setText(speed, (s.pathVelocityMmS * 60).toFixed(0));
  });
  onConnection((c) => panel.classList.toggle("stale", c !== "live"));
  return panel;
}
