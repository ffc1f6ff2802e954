// Preview: the programmed path, the tool-centre path (blue), the junction dots (yellow:
// smooth; red: stop or speed drop below R384, SPEC §7.5), the live tool position while the
// program runs, and the velocity plot; plane choice, zoom and pan (wheel, drag, pinch).
//
// The page draws the server's outline of the selected program (GetPreviewOutline): the paths
// reduced on the server to about a pixel of what is shown, so a program of a million blocks
// costs the browser what a screenful of lines costs. First the whole program; after a zoom or
// pan the page asks for the extent shown and draws it finer when it comes.
import { preview } from "../api";
import { button, h, setText } from "../dom";
import { errorText } from "../format";
import { t } from "../i18n";
import { darkPlot } from "../plot_theme";
import { type Screen, messageLine } from "../screen";
import { subscribe } from "../status";
import { ImageFormat, type Polylines, type PreviewOutline, type Status } from "../gen/cnc/v1/cnc_pb";

/** The drawing's colours are the screen's own (style.css, --pv-*), read once. */
function palette(): Record<"path" | "rapid" | "comp" | "smooth" | "red" | "tool" | "approach", string> {
  const css = getComputedStyle(document.documentElement);
  const v = (name: string, dflt: string) => css.getPropertyValue(`--pv-${name}`).trim() || dflt;
  return { path: v("path", "#c8c8c8"), rapid: v("rapid", "#e08a3c"), comp: v("comp", "#3d8bff"), smooth: v("smooth", "#ffd400"),
    red: v("red", "#ff3030"), tool: v("tool", "#39ff88"), approach: v("approach", "#ff4fd8") };
}
/** Quiet time after a zoom or pan before the finer outline of the extent is asked for. */
const REFINE_AFTER_MS = 250;

interface View { scale: number; ox: number; oy: number }
/** An outline reply and the extent it covers (undefined: the whole program). */
interface Drawing { o: PreviewOutline; extent?: [number, number, number, number] }

export function previewScreen(): Screen {
  const COLORS = palette();
  const msg = messageLine();
  const base = h("canvas", { class: "layer" });
  const overlay = h("canvas", { class: "layer" });
  const stage = h("div", { class: "stage", testid: "preview", "data-state": "empty" }, base, overlay);
  const velocity = h("img", { class: "velocity", testid: "velocity-plot", alt: t("preview.velocity"), hidden: true });
  const plane = h("select", { testid: "preview-plane" },
    h("option", { value: "xy" }, "XY"), h("option", { value: "xz" }, "XZ"), h("option", { value: "yz" }, "YZ"), h("option", { value: "zx" }, t("preview.lathe")));
  const info = h("span", { class: "lbl", testid: "preview-info" });

  let whole: Drawing | undefined;
  let detail: Drawing | undefined;
  let view: View = { scale: 1, ox: 0, oy: 0 };
  let loadedFor = "";
  let tool: [number, number] | undefined;
  let refineTimer = 0;
  /** Counts the refinements asked for: Fit drops one still on its way (it would mark the
   * whole view as a refined extent). */
  let refineSeq = 0;
  let generation = 0;
  /** The approach of a restart from the block status names (Status.restart_block), from
   * where the axes were when it was asked for. */
  let approach: Polylines | undefined;
  let approachFor = "";

  function size(c: HTMLCanvasElement): CanvasRenderingContext2D {
    const dpr = devicePixelRatio || 1;
    const w = stage.clientWidth, hgt = stage.clientHeight;
    if (c.width !== Math.round(w * dpr) || c.height !== Math.round(hgt * dpr)) {
      c.width = Math.round(w * dpr);
      c.height = Math.round(hgt * dpr);
    }
    const g = c.getContext("2d")!;
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, w, hgt);
    return g;
  }

  function fit(): void {
    if (!whole) return;
    const o = whole.o;
    const w = stage.clientWidth || 800, hgt = stage.clientHeight || 600;
    const bw = o.maxHMm - o.minHMm, bh = o.maxVMm - o.minVMm;
    const span = Math.max(bw, bh, 1e-3);
    const scale = 0.9 * Math.min(w / Math.max(bw, span * 0.05), hgt / Math.max(bh, span * 0.05));
    view = { scale, ox: w / 2 - scale * (o.minHMm + o.maxHMm) / 2, oy: hgt / 2 + scale * (o.minVMm + o.maxVMm) / 2 };
  }

  const sx = (x: number) => view.ox + view.scale * x;
  const sy = (y: number) => view.oy - view.scale * y;
  /** The extent shown, mm: min h, min v, max h, max v. */
  function shown(): [number, number, number, number] {
    const w = stage.clientWidth, hgt = stage.clientHeight;
    return [-view.ox / view.scale, (view.oy - hgt) / view.scale, (w - view.ox) / view.scale, view.oy / view.scale];
  }

  function strokeRuns(g: CanvasRenderingContext2D, p: Polylines | undefined, color: string, width: number, dash: number[] = []): void {
    if (!p || !p.xyMm.length) return;
    const xy = p.xyMm, starts = p.starts, n = xy.length / 2;
    g.beginPath();
    for (let k = 0; k < starts.length; k++) {
      const s = starts[k], e = k + 1 < starts.length ? starts[k + 1] : n;
      g.moveTo(sx(xy[2 * s]), sy(xy[2 * s + 1]));
      for (let i = s + 1; i < e; i++) g.lineTo(sx(xy[2 * i]), sy(xy[2 * i + 1]));
    }
    g.strokeStyle = color;
    g.lineWidth = width;
    g.setLineDash(dash);
    g.stroke();
    g.setLineDash([]);
  }

  function dots(g: CanvasRenderingContext2D, xy: number[], color: string, r: number): number {
    g.fillStyle = color;
    g.beginPath();
    for (let i = 0; i < xy.length; i += 2) {
      const x = sx(xy[i]), y = sy(xy[i + 1]);
      g.moveTo(x + r, y);
      g.arc(x, y, r, 0, 2 * Math.PI);
    }
    g.fill();
    return xy.length / 2;
  }

  /** The finer drawing when it covers what is shown, else the whole program's. */
  function current(): Drawing | undefined {
    if (!detail?.extent) return whole;
    const [a, b, c, d] = shown(), [e0, e1, e2, e3] = detail.extent;
    return a >= e0 - 1e-9 && b >= e1 - 1e-9 && c <= e2 + 1e-9 && d <= e3 + 1e-9 ? detail : whole;
  }

  function drawBase(): void {
    const g = size(base);
    const d = current();
    if (!d) return;
    const o = d.o;
    strokeRuns(g, o.rapid, COLORS.rapid, 1.5, [6, 5]);
    strokeRuns(g, o.feed, COLORS.path, 1.5);
    strokeRuns(g, o.compensated, COLORS.comp, 2);
    strokeRuns(g, approach, COLORS.approach, 2, [3, 4]);
    stage.dataset.approachPoints = String((approach?.xyMm.length ?? 0) / 2);
    const smooth = dots(g, o.smoothXyMm, COLORS.smooth, 4);
    const red = dots(g, o.redXyMm, COLORS.red, 5);
    stage.dataset.smoothDots = String(smooth);
    stage.dataset.redDots = String(red);
    stage.dataset.scale = view.scale.toPrecision(4);
    stage.dataset.cellMm = o.cellMm.toPrecision(3);
    stage.dataset.detail = d === detail ? "extent" : "whole";
  }

  function drawTool(): void {
    const g = size(overlay);
    if (!tool || !whole) return;
    const x = sx(tool[0]), y = sy(tool[1]);
    g.strokeStyle = COLORS.tool;
    g.lineWidth = 2;
    g.beginPath();
    g.arc(x, y, 9, 0, 2 * Math.PI);
    g.moveTo(x - 15, y); g.lineTo(x + 15, y);
    g.moveTo(x, y - 15); g.lineTo(x, y + 15);
    g.stroke();
    stage.dataset.tool = `${tool[0].toFixed(3)} ${tool[1].toFixed(3)}`;
  }

  function redraw(): void {
    drawBase();
    drawTool();
  }

  const px = () => ({ widthPx: Math.max(100, stage.clientWidth), heightPx: Math.max(100, stage.clientHeight) });

  /** After a zoom or pan: the extent shown, finer, once the view is still. */
  function refineLater(): void {
    clearTimeout(refineTimer);
    if (!whole) return;
    const seq = ++refineSeq;
    refineTimer = window.setTimeout(async () => {
      const ext = shown(), gen = generation;
      try {
        const o = await preview.getPreviewOutline({ plane: plane.value, minHMm: ext[0], minVMm: ext[1], maxHMm: ext[2], maxVMm: ext[3], ...px() });
        if (gen !== generation || seq !== refineSeq) return;
        detail = { o, extent: ext };
        redraw();
      } catch (e) {
        msg.err(errorText(e));
      }
    }, REFINE_AFTER_MS);
  }

  /** What the drawing is of: the selection (name, blocks) and the job on a plane. A start
   * asks again: the server then answers with the pass the job validated with (a setup
   * changed since the selection), what runs. Opening the screen asks again too (a program
   * selected again by another client with the same name and size). */
  const keyOf = (s: Status) => `${s.program}/${s.blocksTotal}/${s.job}/${plane.value}`;

  async function load(s: Status): Promise<void> {
    // The same program on the same plane keeps the operator's zoom.
    const keep = !!whole && loadedFor.split("/")[0] === s.program && loadedFor.endsWith(`/${plane.value}`);
    loadedFor = keyOf(s);
    const gen = ++generation;
    stage.dataset.state = "loading";
    const t0 = performance.now();
    try {
      if (!keep) {
        whole = detail = undefined;
        velocity.hidden = true;
      }
      const o = await preview.getPreviewOutline({ plane: plane.value, ...px() });
      if (gen !== generation) return;
      whole = { o };
      detail = undefined;
      if (keep) refineLater();
      else fit();
      redraw();
      stage.dataset.mode = "outline";
      stage.dataset.state = "drawn";
      stage.dataset.ms = (performance.now() - t0).toFixed(0);
      setText(info, t("preview.info", { program: o.program, blocks: o.blocks, smooth: String(o.smoothJunctions), red: String(o.redJunctions) }));
      msg.ok("");
      if (!keep) void loadVelocity().catch(() => {});
    } catch (e) {
      stage.dataset.state = "error";
      msg.err(errorText(e));
    }
  }

  async function loadVelocity(): Promise<void> {
    const r = await preview.getPreview({ velocity: true, format: ImageFormat.SVG, widthPx: 1200, heightPx: 300 });
    // The server draws for paper (white); the screen shows it in its own dark colours.
    const svg = darkPlot(new TextDecoder().decode(r.image));
    if (velocity.src) URL.revokeObjectURL(velocity.src);
    velocity.src = URL.createObjectURL(new Blob([svg], { type: "image/svg+xml" }));
    velocity.hidden = false;
  }

  /** The restart approach when status names a block to restart from (a pass on the server,
   * asked again when that block or the plane changes); none otherwise. */
  async function loadApproach(s: Status): Promise<void> {
    const key = s.restartBlock === undefined ? "" : `${s.program}/${s.restartBlock}/${plane.value}`;
    if (key === approachFor) return;
    approachFor = key;
    approach = undefined;
    if (s.restartBlock !== undefined) {
      try {
        approach = (await preview.getPreviewOutline({ plane: plane.value, fromBlock: s.restartBlock, ...px() })).approach;
      } catch {
        approach = undefined;
      }
    }
    if (key === approachFor) redraw();
  }

  let latest: Status | undefined;
  function reload(): void {
    if (latest && latest.program && !el.hidden) void load(latest);
  }

  // The live tool position: the commanded position of the plane's axes (machine
  // coordinates, the tool centre: what the outline's blue path shows under compensation).
  subscribe((s) => {
    latest = s;
    if (!el.hidden && s.program && keyOf(s) !== loadedFor && stage.dataset.state !== "loading") void load(s);
    if (!whole || el.hidden) return;
    void loadApproach(s);
    const [hn, vn] = plane.value.toUpperCase().split("");
    const at = (n: string) => s.axes.find((a) => a.name === n)?.commandedMm ?? 0;
    const p: [number, number] = [at(hn), at(vn)];
    if (!tool || p[0] !== tool[0] || p[1] !== tool[1]) {
      tool = p;
      drawTool();
    }
  });

  // Zoom and pan: the wheel zooms about the pointer; one pointer (mouse or finger) drags;
  // two fingers pinch (zoom about their middle) and pan together.
  function zoom(f: number, cx = stage.clientWidth / 2, cy = stage.clientHeight / 2): void {
    view = { scale: view.scale * f, ox: cx - (cx - view.ox) * f, oy: cy - (cy - view.oy) * f };
    redraw();
    refineLater();
  }
  stage.addEventListener("wheel", (e) => {
    e.preventDefault();
    const r = stage.getBoundingClientRect();
    zoom(e.deltaY < 0 ? 1.25 : 0.8, e.clientX - r.left, e.clientY - r.top);
  }, { passive: false });
  const pointers = new Map<number, { x: number; y: number }>();
  /** Middle and spread of the pointers down (stage coordinates). */
  function gesture(): { x: number; y: number; d: number } {
    const r = stage.getBoundingClientRect();
    const ps = [...pointers.values()];
    const x = ps.reduce((a, p) => a + p.x, 0) / ps.length - r.left;
    const y = ps.reduce((a, p) => a + p.y, 0) / ps.length - r.top;
    const d = ps.length > 1 ? Math.hypot(ps[0].x - ps[1].x, ps[0].y - ps[1].y) : 0;
    return { x, y, d };
  }
  stage.addEventListener("pointerdown", (e) => {
    pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
    stage.setPointerCapture(e.pointerId);
  });
  stage.addEventListener("pointermove", (e) => {
    if (!pointers.has(e.pointerId)) return;
    const before = gesture();
    pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
    const after = gesture();
    const f = pointers.size > 1 && before.d > 0 && after.d > 0 ? after.d / before.d : 1;
    // Zoom about the middle, then move with it.
    view = {
      scale: view.scale * f,
      ox: after.x - (before.x - view.ox) * f,
      oy: after.y - (before.y - view.oy) * f,
    };
    redraw();
    refineLater();
  });
  for (const ev of ["pointerup", "pointercancel"]) stage.addEventListener(ev, (e) => pointers.delete((e as PointerEvent).pointerId));
  plane.addEventListener("change", reload);
  new ResizeObserver(() => { if (whole) { redraw(); refineLater(); } }).observe(stage);

  const el = h("div", { class: "screen preview" },
    h("div", { class: "row" }, h("label", {}, `${t("preview.plane")} `, plane),
      button("−", "preview-zoom-out", () => zoom(0.8), "", "observer"),
      button("+", "preview-zoom-in", () => zoom(1.25), "", "observer"),
      button(t("preview.fit"), "preview-fit", () => { clearTimeout(refineTimer); refineSeq++; fit(); detail = undefined; redraw(); }, "", "observer"),
      info),
    stage,
    h("div", { class: "legend" },
      h("span", { style: `color:${COLORS.path}` }, t("preview.programmed")), h("span", { style: `color:${COLORS.rapid}` }, t("preview.rapid")),
      h("span", { style: `color:${COLORS.comp}` }, t("preview.toolCentre")), h("span", { style: `color:${COLORS.smooth}` }, t("preview.smooth")),
      h("span", { style: `color:${COLORS.red}` }, t("preview.red")), h("span", { style: `color:${COLORS.tool}` }, t("preview.tool")),
      h("span", { style: `color:${COLORS.approach}` }, t("preview.approach"))),
    velocity,
    msg.el);
  return { id: "preview", el, onShow: () => requestAnimationFrame(reload) };
}
