// Homing: the reference run of all axes or of one, and which axes are referenced.
import { machine } from "../api";
import { button, h, setText } from "../dom";
import { errorText } from "../format";
import { t } from "../i18n";
import { type Screen, messageLine } from "../screen";
import { subscribe } from "../status";

export function homingScreen(): Screen {
  const msg = messageLine();
  const rows = h("div", { class: "home-axes" });
  const flags = new Map<string, HTMLElement>();
  const home = (axes: string) => () => {
    msg.ok(t("home.running", { axes: axes || t("home.allAxes") }));
    machine.home({ axes }, { timeoutMs: 600_000 }).then((r) => msg.ok(t("home.done", { axes: r.homed })), (e) => msg.err(errorText(e)));
  };
  subscribe((s) => {
    for (const a of s.axes) {
      let f = flags.get(a.name);
      if (!f) {
        f = h("span", { class: "flag" });
        flags.set(a.name, f);
        rows.append(h("div", { class: "row" }, h("span", { class: "axis" }, a.name), f, button(t("home.axis", { axis: a.name }), `home-${a.name}`, home(a.name))));
      }
      setText(f, t(a.homed ? "home.referenced" : a.homingRequired ? "home.required" : "home.notReferenced"));
      f.className = a.homed ? "flag ok" : "flag err";
    }
  });
  const el = h("div", { class: "screen homing" }, button(t("home.all"), "home-all", home(""), "start"), rows, msg.el);
  return { id: "homing", el };
}
