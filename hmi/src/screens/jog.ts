// Jog: per-axis buttons, a step size (mm) or continuous (move only while pressed), a speed.
// Keyboard: arrow keys X/Y, Page Up/Down Z, held = continuous, on this screen only.
import { machine } from "../api";
import { h } from "../dom";
import { errorText } from "../format";
import { t } from "../i18n";
import { holdToJog, onJogError, press, release } from "../jog";
import { may } from "../session";
import { type Screen, messageLine } from "../screen";
import { subscribe } from "../status";
import { probeControl } from "../probe";
import { touchOffControl } from "../touch_off";

const STEPS_MM = ["0.001", "0.01", "0.1", "1", "10"];
const SPEEDS_MM_MIN = [100, 500, 1000, 3000];

export function jogScreen(): Screen {
  const msg = messageLine();
  onJogError((t) => msg.err(t));
  const step = h("select", { testid: "jog-step" },
    ...STEPS_MM.map((s) => h("option", { value: s }, `${s} mm`)),
    h("option", { value: "continuous" }, t("jog.continuous")));
  step.value = "1";
  const speed = h("select", { testid: "jog-speed" },
    ...SPEEDS_MM_MIN.map((s) => h("option", { value: s }, `${s} mm/min`)));
  speed.value = "1000";
  const axes = h("div", { class: "jog-axes" });
  const built = new Set<string>();
  let screenEl: HTMLElement;

  function jogButton(axis: string, dir: number): HTMLButtonElement {
    const b = h("button", { type: "button", class: "jog", testid: `jog-${axis}-${dir > 0 ? "plus" : "minus"}` },
      `${axis}${dir > 0 ? "+" : "−"}`);
    b.dataset.least = "operator";
    holdToJog(b, () => {
      if (step.value !== "continuous") return false;
      press(axis, dir, Number(speed.value));
      return true;
    });
    b.addEventListener("click", () => {
      if (b.disabled || step.value === "continuous") return;
      machine.jogStep({ axis, stepMm: dir * Number(step.value), speedMmMin: Number(speed.value) })
        .then(() => msg.ok(""), (e) => msg.err(errorText(e)));
    });
    return b;
  }

  subscribe((s) => {
    for (const a of s.axes) {
      if (built.has(a.name)) continue;
      built.add(a.name);
      axes.append(h("div", { class: "jog-axis" }, jogButton(a.name, -1), h("span", { class: "axis" }, a.name), jogButton(a.name, +1)));
    }
  });

  const keys: Record<string, [string, number]> = {
    ArrowLeft: ["X", -1], ArrowRight: ["X", 1], ArrowDown: ["Y", -1], ArrowUp: ["Y", 1],
    PageDown: ["Z", -1], PageUp: ["Z", 1],
  };
  let held = "";
  window.addEventListener("keydown", (e) => {
    const k = keys[e.key];
    if (!k || screenEl.hidden || !may("operator") || (e.target as HTMLElement).matches("input, select, textarea")) return;
    e.preventDefault();
    if (e.repeat || held) return;
    if (!built.has(k[0])) return;
    held = e.key;
    if (step.value === "continuous") press(k[0], k[1], Number(speed.value));
    else machine.jogStep({ axis: k[0], stepMm: k[1] * Number(step.value), speedMmMin: Number(speed.value) }).catch((err) => msg.err(errorText(err)));
  });
  window.addEventListener("keyup", (e) => {
    if (e.key !== held) return;
    held = "";
    release();
  });
  window.addEventListener("blur", () => (held = ""));

  screenEl = h(
    "div",
    { class: "screen jog-screen" },
    h("div", { class: "row" }, h("label", {}, `${t("jog.step")} `, step), h("label", {}, `${t("jog.speed")} `, speed)),
    axes,
    h("p", { class: "hint" }, t("jog.hint")),
    touchOffControl("jog", msg),
    msg.el,
    probeControl("jog"),
  );
  return { id: "jog", el: screenEl };
}
