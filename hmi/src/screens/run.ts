// Run: program, block and line with the listing scrolled to it, progress, overrides, spindle,
// KŘR (the cycle controls are the shell's bar under the screen: cycle.ts).
import { machine, programs } from "../api";
import { fill, h, setText } from "../dom";
import { t } from "../i18n";
import { ioWarnings, warningsKey } from "../io";
import { Listing } from "../listing";
import type { Screen } from "../screen";
import { subscribe } from "../status";
import { MachineState, type Status } from "../gen/cnc/v1/cnc_pb";
import { downloadText } from "./programs";

/** Largest program the Run screen lists (the listing is downloaded once per selection). */
const LISTING_MAX_BYTES = 8 << 20;

function override(
  label: string,
  testid: string,
  min: number,
  max: number,
  send: (p: number) => Promise<unknown>,
): { el: HTMLElement; show(v: number): void } {
  const input = h("input", { type: "range", min, max, step: 1, testid, value: 100 });
  input.dataset.least = "operator";
  const value = h("span", { class: "ov-val" }, "100 %");
  let editing = false;
  input.addEventListener("pointerdown", () => (editing = true));
  input.addEventListener("input", () => setText(value, `${input.value} %`));
  input.addEventListener("change", () => {
    editing = false;
    send(Number(input.value)).catch(() => {});
  });
  return {
    el: h("label", { class: "ov" }, h("span", { class: "ov-label" }, label), input, value),
    show(v: number) {
      if (editing || document.activeElement === input) return;
      input.value = String(Math.round(v));
      setText(value, `${Math.round(v)} %`);
    },
  };
}

export function runScreen(): Screen {
  const program = h("span", { class: "big", testid: "program-name", translate: "no" }, "—");
  const block = h("span", { testid: "block" }, "—");
  const line = h("span", { testid: "line" }, "—");
  const bar = h("div", { class: "bar-fill" });
  const pct = h("span", { testid: "progress" }, "0 %");
  const spindle = h("span", {}, "0");
  const feed = h("span", {}, "—");
  const modal = h("span", { class: "modal", translate: "no" }, "");
  const kr = h("div", { class: "kr", hidden: true });
  const listing = new Listing("run-listing");
  // E-stop, door, limit and forced outputs without opening the I/O screen (one line, shown
  // only while one of them holds).
  const io = h("div", { class: "io-banner compact", testid: "run-io", hidden: true });
  let ioKey = "";

  const feedOv = override(t("ov.feed"), "feed-override", 0, 150, (p) => machine.setOverride({ percent: p }));
  const spinOv = override(t("ov.spindle"), "spindle-override", 50, 120, (p) =>
    machine.setSpindleOverride({ percent: p }),
  );
  const rapidOv = override(t("ov.rapid"), "rapid-override", 0, 100, (p) =>
    machine.setRapidOverride({ percent: p }),
  );

  const el = h(
    "div",
    { class: "screen run" },
    h(
      "div",
      { class: "run-head" },
      h("div", { class: "run-prog" }, h("span", { class: "lbl" }, `${t("run.program")} `), program),
      h("div", {}, h("span", { class: "lbl" }, `${t("run.block")} `), block, h("span", { class: "lbl" }, `  ${t("run.line")} `), line),
      h("div", { class: "bar" }, bar, pct),
      io,
    ),
    h("div", { class: "run-body" }, listing.el, h("div", { class: "run-side" },
      feedOv.el, spinOv.el, rapidOv.el,
      h("div", { class: "kv" }, h("span", { class: "lbl" }, `${t("run.spindle")} `), spindle, ` ${t("unit.rpm")}`),
      h("div", { class: "kv" }, h("span", { class: "lbl" }, `${t("run.feed")} `), feed),
      kr,
      modal,
    )),
  );

  let shown = "";
  let sizeOk = true;
  let lastLine = -1;
  async function loadListing(name: string, key: string): Promise<void> {
    shown = key;
    lastLine = -1;
    if (!name) return listing.setText("");
    const lib = await programs.list({});
    const p = lib.programs.find((q) => q.name === name);
    sizeOk = !!p && Number(p.sizeBytes) <= LISTING_MAX_BYTES;
    // Not in the library (MDI blocks): nothing to list.
    if (!p) return listing.setText("");
    listing.setText(sizeOk ? await downloadText(name) : t("run.tooLarge", { name }));
  }

  subscribe((s: Status) => {
    setText(program, s.program || "—");
    const key = `${s.program}/${s.blocksTotal}`;
    if (key !== shown) {
      // A failed download is tried again after a while, not on every snapshot.
      void loadListing(s.program, key).catch(() => setTimeout(() => (shown = ""), 5000));
    }
    setText(block, s.block !== undefined ? `N${s.block}` : "—");
    setText(line, s.line ? String(s.line) : "—");
    setText(pct, `${s.percent.toFixed(1)} %  (${s.blockIndex}/${s.blocksTotal})`);
    bar.style.width = `${s.percent}%`;
    const running = s.state === MachineState.RUNNING || s.state === MachineState.HOLD;
    if (sizeOk && s.line !== lastLine && (running || s.line > 0)) {
      lastLine = s.line;
      listing.goto(s.line);
    }
    setText(spindle, s.spindleRpm.toFixed(0));
    setText(feed, s.feedProgrammed ? `${s.feedProgrammed} ${t(s.feedMode === "G95" ? "unit.mmRev" : "unit.mmMin")}` : "—");
    setText(modal, [...s.modalGCodes, s.compensation?.code && s.compensation.entry ? `D${s.compensation.entry}` : ""].join(" "));
    feedOv.show(s.overridePercent);
    spinOv.show(s.spindleOverridePercent);
    rapidOv.show(s.rapidOverridePercent);
    const w = ioWarnings(s.io);
    const wk = warningsKey(w);
    if (wk !== ioKey) {
      ioKey = wk;
      fill(io, ...w.map((x) => h("span", { class: `io-warn ${x.kind}`, "data-kind": x.kind }, x.text)));
      io.hidden = w.length === 0;
    }
    const k = s.kr;
    kr.hidden = !k || k.cuttingSpeedMMin <= 0;
    if (k && !kr.hidden) {
      setText(kr, t("run.kr", { v: k.cuttingSpeedMMin.toFixed(1), r: k.radiusMm.toFixed(3), s: k.spindleRpm.toFixed(0) }));
    }
  });
  return { id: "run", el };
}
