// Probing (docs/setup.md, "Probing"): the tool-setter, edge and bore workflows of
// Offsets.ProbeWorkflow, whose results are written into an entry as touch-off writes them.
// A value left empty is the workflow's default (the setter's top, the edge or centre at 0).
// The same panel sits on the Offsets and the Jog screens (test ids `probe-<where>-*`); its
// `data-state` is `idle`, `running`, `done` or `error`.
import { offsets } from "./api";
import { button, h } from "./dom";
import { errorText } from "./format";
import { t } from "./i18n";
import { messageLine } from "./screen";
import { may } from "./session";
import { subscribe } from "./status";
import { ProbeWorkflowKind, type ProbeWorkflowReply } from "./gen/cnc/v1/cnc_pb";
import type { Key } from "./lang/en";

const KINDS: Array<[string, ProbeWorkflowKind, Key]> = [
  ["tool-setter", ProbeWorkflowKind.TOOL_SETTER, "probe.toolSetter"],
  ["edge", ProbeWorkflowKind.EDGE, "probe.edge"],
  ["bore", ProbeWorkflowKind.BORE, "probe.bore"],
];
/** What the value reads, per workflow. */
const VALUE_LABEL: Record<string, Key> = {
  "tool-setter": "probe.valueSetter", edge: "probe.valueEdge", bore: "probe.valueBore",
};

/** The result as the operator reads it: each length written, the bore's diameter. */
function written(entry: number, r: ProbeWorkflowReply): string {
  const lines = r.written.map((w) => t("probe.written", {
    entry, axis: w.axis, length: w.lengthMm.toFixed(4), machine: w.machineMm.toFixed(4),
  }));
  if (r.diameterMm > 0) lines.push(t("probe.diameter", { diameter: r.diameterMm.toFixed(4) }));
  return lines.join("; ");
}

export function probeControl(where: string, done: () => void = () => {}): HTMLElement {
  const id = (part: string): string => `probe-${where}-${part}`;
  const kind = h("select", { testid: id("kind") }, ...KINDS.map(([v, , k]) => h("option", { value: v }, t(k))));
  const entry = h("input", { type: "number", min: 1, max: 99, value: 1, class: "num", testid: id("entry") });
  const axis = h("select", { testid: id("axis") });
  const dir = h("select", { testid: id("dir") }, h("option", { value: "1" }, "+"), h("option", { value: "-1" }, "−"));
  const num = (part: string) => h("input", { type: "number", step: "0.001", class: "num", placeholder: t("probe.default"), testid: id(part) });
  const value = num("value");
  const value2 = num("value2");
  [kind, entry, axis, dir, value, value2].forEach((e) => (e.dataset.least = "operator"));
  subscribe((s) => {
    // Lengths exist for axes 1..4 of the table.
    const names = s.axes.slice(0, 4).map((a) => a.name);
    if (axis.options.length === names.length) return;
    axis.replaceChildren(...names.map((n) => h("option", { value: n }, n)));
  });

  const valueName = h("span", {});
  const edgeOnly = [h("label", {}, `${t("probe.axis")} `, axis), h("label", {}, `${t("probe.direction")} `, dir)];
  const boreOnly = h("label", {}, `${t("probe.value2")} `, value2);
  function show(): void {
    valueName.textContent = `${t(VALUE_LABEL[kind.value])} `;
    edgeOnly.forEach((l) => (l.hidden = kind.value !== "edge"));
    boreOnly.hidden = kind.value !== "bore";
  }
  kind.addEventListener("change", show);
  show();

  const result = messageLine();
  result.el.dataset.testid = id("result");
  const start = button(t("probe.start"), id("start"), probe);
  const panel = h("div", { class: "probe", testid: id("panel"), "data-state": "idle" });
  let running = false;
  function state(s: "running" | "done" | "error", text: string): void {
    running = s === "running";
    start.disabled = running || !may("operator");
    panel.dataset.state = s;
    if (s === "error") result.err(text);
    else result.ok(text);
    result.el.classList.toggle("busy", running);
  }

  const opt = (e: HTMLInputElement): number | undefined => (e.value.trim() === "" ? undefined : Number(e.value));
  function probe(): void {
    if (running) return;
    const n = Number(entry.value);
    const k = KINDS.find(([v]) => v === kind.value)![1];
    state("running", t("probe.running"));
    offsets.probeWorkflow({
      kind: k, entry: n, axis: k === ProbeWorkflowKind.EDGE ? axis.value : "", direction: Number(dir.value),
      valueMm: opt(value), value2Mm: k === ProbeWorkflowKind.BORE ? opt(value2) : undefined, workOffset: "",
    }).then((r) => {
      state("done", written(n, r));
      done();
    }, (e) => state("error", errorText(e)));
  }
  panel.append(
    h("div", { class: "row" },
      h("span", {}, t("probe.title")), kind,
      h("label", {}, "D ", entry), ...edgeOnly,
      h("label", {}, valueName, value), boreOnly,
      start),
    result.el);
  return panel;
}
