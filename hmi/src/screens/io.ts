// I/O: a lamp per input and output (docs/io.md), live from the status stream (`Status.io`),
// with the e-stop chain, the door and limit switches as a banner. An admin forces outputs
// (commissioning) after a confirmation naming the output and the value, and on a simulated
// machine sets inputs. Rows are built once per list of names and then only updated: the
// status arrives 30 times a second.
import { machine } from "../api";
import { button, fill, h, setText } from "../dom";
import { errorText } from "../format";
import { t } from "../i18n";
import { ioWarnings, warningsKey } from "../io";
import { type Screen, messageLine } from "../screen";
import { onRole } from "../session";
import { subscribe } from "../status";
import type { IoList, IoPoint } from "../gen/cnc/v1/cnc_pb";

type Row = { el: HTMLElement; value: HTMLElement; tags: HTMLElement };

/** A value as the confirmation and the buttons name it. */
const valueName = (v: boolean | undefined) => t(v === undefined ? "io.valueRelease" : v ? "io.valueOn" : "io.valueOff");

export function ioScreen(): Screen {
  const msg = messageLine();
  const banner = h("div", { class: "io-banner", testid: "io-banner" });
  const inputs = h("div", { class: "io-list", testid: "io-inputs" });
  const outputs = h("div", { class: "io-list", testid: "io-outputs" });
  const rows = new Map<string, Row>();
  let key = "";
  let bannerKey = "-";

  // The confirmation: forcing an output moves real things (coolant, the spindle's enable).
  const question = h("p", { testid: "io-confirm-text" });
  let pending: (() => void) | undefined;
  const dialog = h("dialog", { class: "confirm", testid: "io-confirm" }, question,
    h("div", { class: "row" },
      button(t("io.force"), "io-confirm-yes", () => {
        dialog.close();
        pending?.();
      }, "danger", "observer"),
      button(t("io.cancel"), "io-confirm-no", () => dialog.close(), "", "observer")));
  dialog.addEventListener("close", () => (pending = undefined));

  function force(name: string, value: boolean | undefined): void {
    setText(question, value === undefined
      ? t("io.askRelease", { name })
      : t("io.askForce", { name, value: valueName(value) }));
    dialog.dataset.name = name;
    dialog.dataset.value = value === undefined ? "release" : value ? "1" : "0";
    pending = () => {
      machine.forceOutput({ name, value }).then(
        () => msg.ok(value === undefined ? t("io.released", { name }) : t("io.forcedTo", { name, value: value ? 1 : 0 })),
        (e) => msg.err(errorText(e)));
    };
    dialog.showModal();
  }

  function simSet(name: string, value: boolean | undefined): void {
    machine.simSetInput({ name, value }).then(
      () => msg.ok(value === undefined ? t("io.simAgain", { name }) : t("io.setTo", { name, value: value ? 1 : 0 })),
      (e) => msg.err(errorText(e)));
  }

  function row(p: IoPoint, output: boolean): HTMLElement {
    const value = h("span", { class: "io-value" });
    const tags = h("span", { class: "io-tags" });
    const m = [...p.on.map((x) => t(output ? "io.switchesOn" : "io.confirms", { m: x })), ...p.off.map((x) => t("io.switchesOff", { m: x }))];
    // The function and the wiring are the configuration's own names (docs/io.md): not translated.
    const ids = [p.function, p.wiring].filter(Boolean).join(" · ");
    const about = h("div", { class: "io-about" }, h("span", { translate: "no" }, ids), ids && m.length ? " · " : "", m.join(" · "));
    const kind = output ? "out" : "in";
    const act = output
      ? h("div", { class: "io-act admin-only" },
        button(t("io.on"), `io-force-${p.name}-on`, () => force(p.name, true), "", "admin"),
        button(t("io.off"), `io-force-${p.name}-off`, () => force(p.name, false), "", "admin"),
        button(t("io.release"), `io-force-${p.name}-release`, () => force(p.name, undefined), "", "admin"))
      : h("div", { class: "io-act admin-only sim-only" },
        button("0", `io-sim-${p.name}-0`, () => simSet(p.name, false), "", "admin"),
        button("1", `io-sim-${p.name}-1`, () => simSet(p.name, true), "", "admin"),
        button(t("io.sim"), `io-sim-${p.name}-release`, () => simSet(p.name, undefined), "", "admin"));
    const el = h("div", { class: "io-point", testid: `io-${kind}-${p.name}`, "data-name": p.name },
      h("div", { class: "io-main" }, h("span", { class: "lamp" }), h("span", { class: "io-name", translate: "no" }, p.name), value, tags),
      about,
      act);
    rows.set(`${kind}:${p.name}`, { el, value, tags });
    return el;
  }

  function update(kind: string, p: IoPoint): void {
    const r = rows.get(`${kind}:${p.name}`);
    if (!r) return;
    const v = p.value ? "1" : "0";
    if (r.el.dataset.value !== v) r.el.dataset.value = v;
    r.el.classList.toggle("on", p.value);
    r.el.classList.toggle("forced", p.forced);
    r.el.classList.toggle("waited", p.waitedFor);
    r.el.classList.toggle("timed-out", p.waitTimedOut);
    r.el.dataset.forced = p.forced ? "1" : "0";
    setText(r.value, v);
    const tags = [p.forced ? t("io.tagForced") : "", p.waitedFor ? t("io.tagWaited") : "", p.waitTimedOut ? t("io.tagTimedOut") : ""];
    setText(r.tags, tags.filter(Boolean).join(" "));
  }

  function draw(io: IoList): void {
    const k = [io.simulated, ...io.inputs.map((p) => p.name), "|", ...io.outputs.map((p) => p.name)].join(",");
    if (k !== key) {
      key = k;
      rows.clear();
      fill(inputs, ...io.inputs.map((p) => row(p, false)));
      fill(outputs, ...io.outputs.map((p) => row(p, true)));
      el.classList.toggle("simulated", io.simulated);
    }
    io.inputs.forEach((p) => update("in", p));
    io.outputs.forEach((p) => update("out", p));
    const w = ioWarnings(io);
    const bk = warningsKey(w);
    if (bk !== bannerKey) {
      bannerKey = bk;
      fill(banner, ...w.map((x) => h("span", { class: `io-warn ${x.kind}`, "data-kind": x.kind }, x.text)));
      banner.hidden = w.length === 0;
    }
  }

  const el = h("div", { class: "screen io" }, banner,
    h("h3", {}, t("io.inputs")), inputs, h("h3", {}, t("io.outputs")), outputs, msg.el, dialog);
  // Hidden: nothing to draw (the Run screen's strip shows the warnings meanwhile).
  subscribe((s) => {
    if (!el.hidden && s.io) draw(s.io);
  });
  onRole((r) => el.classList.toggle("admin", r === "admin"));
  return { id: "io", el };
}
