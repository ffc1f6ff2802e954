// Touch-off (docs/setup.md): entry n's length of an axis set so that where the axis stands
// reads the value typed, through Offsets.TouchOff (file and memory, as every table edit). The
// same control sits on the Offsets and the Jog screens (test ids `touch-off-<where>-*`).
import { offsets } from "./api";
import { button, h } from "./dom";
import { errorText } from "./format";
import { t } from "./i18n";
import { subscribe } from "./status";

export function touchOffControl(
  where: string,
  msg: { ok(t: string): void; err(t: string): void },
  done: () => void = () => {},
): HTMLElement {
  const id = (part: string): string => `touch-off-${where}-${part}`;
  const entry = h("input", { type: "number", min: 1, max: 99, value: 1, class: "num", testid: id("entry") });
  const axis = h("select", { testid: id("axis") });
  const value = h("input", { type: "number", step: "0.001", value: 0, class: "num", testid: id("value") });
  [entry, axis, value].forEach((e) => (e.dataset.least = "operator"));
  subscribe((s) => {
    // Lengths exist for axes 1..4 of the table.
    const names = s.axes.slice(0, 4).map((a) => a.name);
    if (axis.options.length === names.length) return;
    axis.replaceChildren(...names.map((n) => h("option", { value: n }, n)));
  });

  function touch(): void {
    offsets.touchOff({ entry: Number(entry.value), axis: axis.value, valueMm: Number(value.value), workOffset: "" })
      .then((r) => {
        msg.ok(t("touchOff.done", { entry: entry.value, axis: axis.value, length: r.lengthMm.toFixed(4) }));
        done();
      }, (e) => msg.err(errorText(e)));
  }
  return h("div", { class: "row touch-off" },
    h("span", {}, t("touchOff.title")),
    h("label", {}, "D ", entry), h("label", {}, `${t("touchOff.axis")} `, axis),
    h("label", {}, `${t("touchOff.value")} `, value),
    button(t("touchOff.submit"), id("submit"), touch));
}
