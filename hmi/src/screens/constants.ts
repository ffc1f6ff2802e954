// Constants: the machine constants R0..R999, each the controller reads named with its unit and
// meaning (GetConstants); an admin changes values (all or nothing), and the screen says which
// need a restart of cncd (restart_required).
import { constants } from "../api";
import { button, fill, h } from "../dom";
import { errorText } from "../format";
import { lang, t } from "../i18n";
import { constantsCs, unitCs } from "../lang/constants_cs";
import { diagText } from "../server_text";
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
      const cs = lang() === "cs";
      fill(table, h("tr", {}, h("th", {}, t("const.number")), h("th", {}, t("const.name")), h("th", {}, t("const.value")), h("th", { class: "dec" }, t("const.decades"))),
        ...r.constants.map((c) => {
          // A constant the controller reads has a name, a unit and a meaning (the kernel's
          // table); the others are only numbers in the file.
          // In Czech the manuals' names (lang/constants_cs.ts), keyed by the constant's number.
          const [name, meaning] = (cs && constantsCs.get(c.number)) || [c.name, c.meaning];
          const what = c.name
            ? h("td", { class: "c-what" }, h("span", { class: "c-name" }, name), h("span", { class: "c-meaning" }, meaning))
            : h("td", { class: "c-what unread" }, t("const.unread"));
          const tr = h("tr", { "data-number": String(c.number) }, h("td", {}, `R${c.number}`), what,
            h("td", { class: "c-value" }, h("span", {}, c.text), h("span", { class: "c-unit" }, cs ? unitCs(c.unit) : c.unit),
              c.isDefault ? h("span", { class: "c-default" }, t("const.default")) : null),
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
      const restart = r.restartRequired.length ? t("const.restart", { list: r.restartRequired.map((n) => `R${n}`).join(", ") }) : "";
      const warn = r.diagnostics.map((d) => diagText(d.code, d.message)).join("; ");
      msg.ok(`${t("const.saved", { n: number.value })}${restart}${warn ? `; ${warn}` : ""}`);
      return refresh();
    }, (e) => msg.err(errorText(e)));
  }
  const el = h("div", { class: "screen constants" },
    h("div", { class: "row" }, h("label", {}, "R ", number), h("label", {}, `${t("const.value")} `, value),
      button(t("const.save"), "constant-save", save, "", "admin")),
    msg.el,
    h("div", { class: "scroll" }, table));
  return { id: "constants", el, onShow: () => void refresh() };
}
