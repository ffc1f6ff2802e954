// The manual tool change prompt (M6, docs/setup.md): while the program holds for a tool, a
// panel over the screen names the tool and its entry (radius, lengths); Confirm is Resume
// (Cycle Start confirms as well). It goes away when the status no longer holds for a tool.
import { machine } from "./api";
import { button, h, setText } from "./dom";
import { errorText } from "./format";
import { t } from "./i18n";
import { subscribe } from "./status";

export function toolChangeDialog(report: (text: string) => void): HTMLElement {
  const text = h("p", { testid: "tool-change-text" });
  const entry = h("p", { testid: "tool-change-entry" });
  const el = h("div", { class: "tool-change", testid: "tool-change-dialog", role: "dialog" },
    h("h2", {}, t("toolChange.title")), text, entry,
    h("div", { class: "row" }, button(t("toolChange.confirm"), "tool-change-confirm", () => {
      machine.resume({}).catch((e) => report(errorText(e)));
    }, "start")));
  el.hidden = true;
  subscribe((s) => {
    const tc = s.toolChange;
    el.hidden = !tc;
    if (!tc) return;
    el.dataset.tool = String(tc.tool);
    setText(text, tc.tool === 0 ? t("toolChange.empty") : t("toolChange.put", { tool: String(tc.tool) }));
    const lengths = tc.lengthMm.map((v) => v.toFixed(3)).join(" ");
    setText(entry, tc.tool === 0 ? "" : t("toolChange.entry", {
      entry: String(tc.tool).padStart(2, "0"), radius: tc.radiusMm.toFixed(3), lengths,
    }));
  });
  return el;
}
