// Run: program, block and line with the listing scrolled to it, progress, overrides, spindle,
// KŘR, and the cycle controls (start, hold, resume, reset, single block, optional stop).
import { machine, programs } from "../api";
import { button, fill, h, setText } from "../dom";
import { errorText } from "../format";
import { ioWarnings, warningsKey } from "../io";
import { Listing } from "../listing";
import type { Screen } from "../screen";
import { messageLine } from "../screen";
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
  const msg = messageLine();
  const call = (f: () => Promise<unknown>) => () =>
    f().then(() => msg.ok(""), (e) => msg.err(errorText(e)));
  const program = h("span", { class: "big", testid: "program-name" }, "—");
  const block = h("span", { testid: "block" }, "—");
  const line = h("span", { testid: "line" }, "—");
  const bar = h("div", { class: "bar-fill" });
  const pct = h("span", { testid: "progress" }, "0 %");
  const spindle = h("span", {}, "0");
  const feed = h("span", {}, "—");
  const modal = h("span", { class: "modal" }, "");
  const kr = h("div", { class: "kr", hidden: true });
  const listing = new Listing("run-listing");
  // E-stop, door, limit and forced outputs without opening the I/O screen (one line, shown
  // only while one of them holds).
  const io = h("div", { class: "io-banner compact", testid: "run-io", hidden: true });
  let ioKey = "";

  const feedOv = override("Feed", "feed-override", 0, 150, (p) => machine.setOverride({ percent: p }));
  const spinOv = override("Spindle", "spindle-override", 50, 120, (p) =>
    machine.setSpindleOverride({ percent: p }),
  );
  const rapidOv = override("Rapid", "rapid-override", 0, 100, (p) =>
    machine.setRapidOverride({ percent: p }),
  );
  const single = button("Single block", "single-block", () =>
    call(() => machine.setSingleBlock({ enabled: !single.classList.contains("active") }))(),
  "toggle");
  const optStop = button("Optional stop", "optional-stop", () =>
    call(() => machine.setOptionalStop({ on: !optStop.classList.contains("active") }))(),
  "toggle");

  const controls = h(
    "div",
    { class: "cycle" },
    button("Cycle start", "cycle-start", call(() => machine.start({})), "start"),
    button("Feed hold", "feed-hold", call(() => machine.hold({})), "hold"),
    button("Resume", "resume", call(() => machine.resume({})), "resume"),
    button("Reset", "reset", call(() => machine.reset({})), "reset"),
    single,
    optStop,
  );

  const el = h(
    "div",
    { class: "screen run" },
    h(
      "div",
      { class: "run-head" },
      h("div", {}, h("span", { class: "lbl" }, "Program "), program),
      h("div", {}, h("span", { class: "lbl" }, "Block "), block, h("span", { class: "lbl" }, "  Line "), line),
      h("div", { class: "bar" }, bar, pct),
      io,
    ),
    h("div", { class: "run-body" }, listing.el, h("div", { class: "run-side" },
      feedOv.el, spinOv.el, rapidOv.el,
      h("div", { class: "kv" }, h("span", { class: "lbl" }, "Spindle "), spindle, " rpm"),
      h("div", { class: "kv" }, h("span", { class: "lbl" }, "Feed "), feed),
      kr,
      modal,
    )),
    controls,
    msg.el,
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
    listing.setText(sizeOk ? await downloadText(name) : `(${name}: too large to list here)`);
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
    setText(feed, s.feedProgrammed ? `${s.feedProgrammed} ${s.feedMode === "G95" ? "mm/rev" : "mm/min"}` : "—");
    setText(modal, [...s.modalGCodes, s.compensation?.code && s.compensation.entry ? `D${s.compensation.entry}` : ""].join(" "));
    feedOv.show(s.overridePercent);
    spinOv.show(s.spindleOverridePercent);
    rapidOv.show(s.rapidOverridePercent);
    single.classList.toggle("active", s.singleBlock);
    optStop.classList.toggle("active", s.optionalStop);
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
      setText(kr, `KŘR  v ${k.cuttingSpeedMMin.toFixed(1)} m/min  r ${k.radiusMm.toFixed(3)} mm  S ${k.spindleRpm.toFixed(0)} rpm`);
    }
  });
  return { id: "run", title: "Run", el };
}
