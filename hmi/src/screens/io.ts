// I/O: a lamp per input and output (docs/io.md), live from the status stream (`Status.io`),
// with the e-stop chain, the door and limit switches as a banner. An admin forces outputs
// (commissioning) after a confirmation naming the output and the value, and on a simulated
// machine sets inputs. Rows are built once per list of names and then only updated: the
// status arrives 30 times a second.
import { machine } from "../api";
import { button, fill, h, setText } from "../dom";
import { errorText } from "../format";
import { ioWarnings, warningsKey } from "../io";
import { type Screen, messageLine } from "../screen";
import { onRole } from "../session";
import { subscribe } from "../status";
import type { IoList, IoPoint } from "../gen/cnc/v1/cnc_pb";

type Row = { el: HTMLElement; value: HTMLElement; tags: HTMLElement };

/** A value as the confirmation and the buttons name it. */
const valueName = (v: boolean | undefined) => (v === undefined ? "release" : v ? "1 (on)" : "0 (off)");

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
      button("Force", "io-confirm-yes", () => {
        dialog.close();
        pending?.();
      }, "danger", "observer"),
      button("Cancel", "io-confirm-no", () => dialog.close(), "", "observer")));
  dialog.addEventListener("close", () => (pending = undefined));

  function force(name: string, value: boolean | undefined): void {
    setText(question, value === undefined
      ? `Release output ${name}? It goes back to what the controller sets.`
      : `Force output ${name} to ${valueName(value)}? It stays so until released, Reset or a restart.`);
    dialog.dataset.name = name;
    dialog.dataset.value = value === undefined ? "release" : value ? "1" : "0";
    pending = () => {
      machine.forceOutput({ name, value }).then(
        () => msg.ok(value === undefined ? `${name} released` : `${name} forced to ${value ? 1 : 0}`),
        (e) => msg.err(errorText(e)));
    };
    dialog.showModal();
  }

  function simSet(name: string, value: boolean | undefined): void {
    machine.simSetInput({ name, value }).then(
      () => msg.ok(value === undefined ? `${name}: simulated value again` : `${name} set to ${value ? 1 : 0}`),
      (e) => msg.err(errorText(e)));
  }

  function row(p: IoPoint, output: boolean): HTMLElement {
    const value = h("span", { class: "io-value" });
    const tags = h("span", { class: "io-tags" });
    const m = [...p.on.map((x) => (output ? `on ${x}` : `confirms ${x}`)), ...p.off.map((x) => `off ${x}`)];
    const about = [p.function, p.wiring, ...m].filter(Boolean).join(" · ");
    const kind = output ? "out" : "in";
    const act = output
      ? h("div", { class: "io-act admin-only" },
        button("On", `io-force-${p.name}-on`, () => force(p.name, true), "", "admin"),
        button("Off", `io-force-${p.name}-off`, () => force(p.name, false), "", "admin"),
        button("Release", `io-force-${p.name}-release`, () => force(p.name, undefined), "", "admin"))
      : h("div", { class: "io-act admin-only sim-only" },
        button("0", `io-sim-${p.name}-0`, () => simSet(p.name, false), "", "admin"),
        button("1", `io-sim-${p.name}-1`, () => simSet(p.name, true), "", "admin"),
        button("Sim", `io-sim-${p.name}-release`, () => simSet(p.name, undefined), "", "admin"));
    const el = h("div", { class: "io-point", testid: `io-${kind}-${p.name}`, "data-name": p.name },
      h("div", { class: "io-main" }, h("span", { class: "lamp" }), h("span", { class: "io-name" }, p.name), value, tags),
      h("div", { class: "io-about" }, about),
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
    const tags = [p.forced ? "FORCED" : "", p.waitedFor ? "WAITED FOR" : "", p.waitTimedOut ? "WAIT TIMED OUT" : ""];
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
    h("h3", {}, "Inputs"), inputs, h("h3", {}, "Outputs"), outputs, msg.el, dialog);
  // Hidden: nothing to draw (the Run screen's strip shows the warnings meanwhile).
  subscribe((s) => {
    if (!el.hidden && s.io) draw(s.io);
  });
  onRole((r) => el.classList.toggle("admin", r === "admin"));
  return { id: "io", title: "I/O", el };
}
