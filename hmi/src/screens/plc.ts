// PLC: the AKRR_* cells of memory area 1 with unit, access and range; an operator writes the
// input cells. Refreshed every second while the screen is shown.
import { plc } from "../api";
import { button, fill, h } from "../dom";
import { errorText } from "../format";
import { t } from "../i18n";
import { type Screen, messageLine } from "../screen";
import { CellAccess } from "../gen/cnc/v1/cnc_pb";

export function plcScreen(): Screen {
  const msg = messageLine();
  const table = h("table", { class: "list", testid: "plc-table" });
  let timer: number | undefined;
  let el: HTMLElement;

  async function refresh(): Promise<void> {
    if (el.hidden) {
      window.clearInterval(timer);
      timer = undefined;
      return;
    }
    if (document.activeElement?.closest("table") === table) return;
    try {
      const r = await plc.listCells({});
      fill(table, h("tr", {}, ...[t("plc.cell"), t("plc.address"), t("plc.value"), t("plc.unit"), t("plc.range"), ""].map((x) => h("th", {}, x))),
        ...r.cells.map((c) => {
          const rw = c.access === CellAccess.READ_WRITE;
          let write: HTMLElement | string = t("plc.readOnly");
          if (rw) {
            const input = h("input", { type: "number", class: "num", value: String(c.value) });
            input.dataset.least = "operator";
            write = h("span", {}, input, button(t("plc.write"), undefined, () => {
              plc.writeCell({ cell: { cell: { case: "name", value: c.name } }, value: BigInt(input.value) })
                .then(() => msg.ok(t("plc.written", { name: c.name })), (e) => msg.err(errorText(e)));
            }));
          }
          return h("tr", { title: c.description }, h("td", { translate: "no" }, c.name), h("td", {}, `0x${c.address.toString(16).toUpperCase()}`),
            h("td", {}, String(c.value)), h("td", {}, c.unit.replace(/\brpm\b/, t("unit.rpm"))), h("td", {}, `${c.min}…${c.max}`), h("td", {}, write));
        }));
    } catch (e) {
      msg.err(errorText(e));
    }
  }
  el = h("div", { class: "screen plc" }, msg.el, h("div", { class: "scroll" }, table));
  return {
    id: "plc", el, onShow: () => {
      void refresh();
      timer ??= window.setInterval(() => void refresh(), 1000);
    },
  };
}
