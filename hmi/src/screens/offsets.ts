// Offsets: the TAB0.KOR table in memory; an operator edits an entry (radius, lengths) with the
// server's validation (a refused value changes nothing and says why).
import { offsets } from "../api";
import { button, fill, h } from "../dom";
import { errorText } from "../format";
import { t } from "../i18n";
import { probeControl } from "../probe";
import { touchOffControl } from "../touch_off";
import { type Screen, messageLine } from "../screen";
import type { OffsetEntry } from "../gen/cnc/v1/cnc_pb";

export function offsetsScreen(): Screen {
  const msg = messageLine();
  const table = h("table", { class: "list", testid: "offset-table" });
  const all = h("input", { type: "checkbox" });
  const entry = h("input", { type: "number", min: 1, max: 99, testid: "offset-entry", class: "num" });
  const fields = [0, 1, 2, 3, 4].map(() => h("input", { type: "number", step: "0.001", class: "num" }));
  entry.dataset.least = "operator";
  fields.forEach((f) => (f.dataset.least = "operator"));
  let labels = ["R", "L1", "L2", "L3", "L4"];

  function pick(e: OffsetEntry): void {
    entry.value = String(e.entry);
    fields[0].value = String(e.radiusMm);
    e.lengthMm.forEach((v, i) => (fields[i + 1].value = String(v)));
  }

  async function refresh(): Promise<void> {
    try {
      const r = await offsets.getOffsets({ includeZero: all.checked });
      if (r.labels.length === 5) labels = r.labels;
      fill(table, h("tr", {}, h("th", {}, "D"), ...labels.map((l) => h("th", {}, l)), h("th", {}, "")),
        ...r.entries.map((e) => {
          const tr = h("tr", { "data-entry": e.entry }, h("td", {}, String(e.entry)), h("td", {}, e.radiusMm.toFixed(3)),
            ...e.lengthMm.map((v) => h("td", {}, v.toFixed(3))), h("td", {}, e.changedByProgram ? "G92" : ""));
          tr.addEventListener("click", () => pick(e));
          return tr;
        }));
    } catch (e) {
      msg.err(errorText(e));
    }
  }

  function save(): void {
    const v = fields.map((f) => (f.value.trim() === "" ? undefined : Number(f.value)));
    offsets.setOffset({ entry: Number(entry.value), radiusMm: v[0], length1Mm: v[1], length2Mm: v[2], length3Mm: v[3], length4Mm: v[4] })
      .then(() => { msg.ok(t("offsets.saved", { entry: entry.value })); return refresh(); }, (e) => msg.err(errorText(e)));
  }
  all.addEventListener("change", () => void refresh());
  const el = h("div", { class: "screen offsets" },
    h("label", { class: "check" }, all, ` ${t("offsets.all")}`),
    h("div", { class: "scroll" }, table),
    h("div", { class: "row" }, h("label", {}, "D ", entry), ...fields.map((f, i) => h("label", {}, `${labels[i] ?? ""} `, f)),
      button(t("offsets.save"), "offset-save", save)),
    touchOffControl("offsets", msg, () => void refresh()),
    msg.el,
    probeControl("offsets", () => void refresh()));
  return { id: "offsets", el, onShow: () => void refresh() };
}
