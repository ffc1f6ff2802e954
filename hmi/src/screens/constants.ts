// Constants: the machine constants R0..R999, each the controller reads named with its unit and
// meaning (GetConstants); an admin changes values (all or nothing), and the screen says which
// need a restart of cncd (restart_required).
import { constants } from "../api";
import { button, fill, h } from "../dom";
import { errorText } from "../format";
import { type Screen, messageLine } from "../screen";

export function constantsScreen(): Screen {
  const msg = messageLine();
  const table = h("table", { class: "list", testid: "constants-table" });
  const number = h("input", { type: "number", min: 0, max: 999, class: "num", testid: "constant-number" });
  const value = h("input", { type: "number", step: "0.001", class: "num", testid: "constant-value" });
  number.dataset.least = "admin";
  value.dataset.least = "admin";

  async function refresh(): Promise<void> {
    try {
      const r = await constants.getConstants({});
      fill(table, h("tr", {}, h("th", {}, "R"), h("th", {}, "constant"), h("th", {}, "value"), h("th", { class: "dec" }, "decades 8…1")),
        ...r.constants.map((c) => {
          // A constant the controller reads has a name, a unit and a meaning (the kernel's
          // table); the others are only numbers in the file.
          const what = c.name
            ? h("td", { class: "c-what" }, h("span", { class: "c-name" }, c.name), h("span", { class: "c-meaning" }, c.meaning))
            : h("td", { class: "c-what unread" }, "not read by this controller");
          const tr = h("tr", { "data-number": String(c.number) }, h("td", {}, `R${c.number}`), what,
            h("td", { class: "c-value" }, h("span", {}, c.text), h("span", { class: "c-unit" }, c.unit),
              c.isDefault ? h("span", { class: "c-default" }, "default") : null),
            h("td", { class: "dec" }, [...c.decades].reverse().join(" ")));
          tr.addEventListener("click", () => { number.value = String(c.number); value.value = String(c.value); });
          return tr;
        }));
    } catch (e) {
      msg.err(errorText(e));
    }
  }

  function save(): void {
    constants.setConstants({ values: [{ number: Number(number.value), value: Number(value.value) }] }).then((r) => {
      const restart = r.restartRequired.length ? `; restart cncd for ${r.restartRequired.map((n) => `R${n}`).join(", ")}` : "";
      const warn = r.diagnostics.map((d) => d.message).join("; ");
      msg.ok(`R${number.value} saved${restart}${warn ? `; ${warn}` : ""}`);
      return refresh();
    }, (e) => msg.err(errorText(e)));
  }
  const el = h("div", { class: "screen constants" },
    h("div", { class: "row" }, h("label", {}, "R ", number), h("label", {}, "value ", value),
      button("Save (admin)", "constant-save", save, "", "admin")),
    msg.el,
    h("div", { class: "scroll" }, table));
  return { id: "constants", title: "Constants", el, onShow: () => void refresh() };
}
