// MDI: one block typed by the operator, with a history kept in this browser (recall with a
// tap, or with the arrow keys in the field).
import { machine } from "../api";
import { button, fill, h } from "../dom";
import { errorText } from "../format";
import { t } from "../i18n";
import { type Screen, messageLine } from "../screen";

const KEY = "cnc.mdi.history";
const KEEP = 50;

export function mdiScreen(): Screen {
  const msg = messageLine();
  const input = h("input", { type: "text", testid: "mdi-input", placeholder: "G1 X10 F500", autocomplete: "off", class: "mdi" });
  input.dataset.least = "operator";
  const list = h("ul", { class: "history", testid: "mdi-history", translate: "no" });
  const history: string[] = JSON.parse(localStorage.getItem(KEY) ?? "[]");
  let cursor = -1;

  function draw(): void {
    fill(list, ...history.map((b) => {
      const li = h("li", {}, b);
      li.addEventListener("click", () => (input.value = b));
      return li;
    }));
  }

  function send(): void {
    const block = input.value.trim();
    if (!block) return;
    machine.mdi({ block }).then(
      () => {
        msg.ok(t("mdi.sent", { block }));
        const i = history.indexOf(block);
        if (i >= 0) history.splice(i, 1);
        history.unshift(block);
        history.length = Math.min(history.length, KEEP);
        localStorage.setItem(KEY, JSON.stringify(history));
        input.value = "";
        cursor = -1;
        draw();
      },
      (e) => msg.err(errorText(e)),
    );
  }

  input.addEventListener("keydown", (e) => {
    if (e.key === "Enter") send();
    else if (e.key === "ArrowUp" || e.key === "ArrowDown") {
      e.preventDefault();
      cursor = Math.max(-1, Math.min(history.length - 1, cursor + (e.key === "ArrowUp" ? 1 : -1)));
      input.value = cursor >= 0 ? history[cursor] : "";
    }
  });
  draw();
  const el = h(
    "div",
    { class: "screen mdi" },
    h("div", { class: "row" }, input, button(t("mdi.send"), "mdi-send", send, "start")),
    msg.el,
    h("h3", {}, t("mdi.history")),
    list,
  );
  return { id: "mdi", el, onShow: () => input.focus() };
}
