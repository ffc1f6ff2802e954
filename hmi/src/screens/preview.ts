// Preview: the programmed path, the tool-centre path (blue), the junction dots (yellow:
// smooth; red: stop or speed drop below R384, SPEC §7.5), the live tool position while the
// program runs, and the velocity plot; plane choice, zoom and pan.
//
// Up to DATA_MAX_BLOCKS blocks the page draws the program itself from GetPreviewData (typed
// arrays; segments shorter than a pixel are skipped, dots sharing a pixel drawn once). A
// larger (CAM-size) program is shown as the server's picture of one R387 page (GetPreview),
// so the browser never holds a million blocks.
import { preview } from "../api";
import { button, h, setText } from "../dom";
import { errorText } from "../format";
import { type Box, type Segments, bounds, segments } from "../geometry";
import { type Screen, messageLine } from "../screen";
import { subscribe } from "../status";
import { ImageFormat, JunctionClass, type PreviewData, type Status } from "../gen/cnc/v1/cnc_pb";

const DATA_MAX_BLOCKS = 20_000;
const COLORS = { path: "#c8c8c8", rapid: "#e08a3c", comp: "#3d8bff", smooth: "#ffd400", red: "#ff3030", tool: "#39ff88" };

interface View { scale: number; ox: number; oy: number }

export function previewScreen(): Screen {
  const msg = messageLine();
  const base = h("canvas", { class: "layer" });
  const overlay = h("canvas", { class: "layer" });
  const picture = h("img", { class: "layer picture", hidden: true, alt: "preview picture" });
  const stage = h("div", { class: "stage", testid: "preview", "data-state": "empty" }, base, picture, overlay);
  const velocity = h("img", { class: "velocity", testid: "velocity-plot", alt: "velocity plot", hidden: true });
  const plane = h("select", { testid: "preview-plane" },
    h("option", { value: "xy" }, "XY"), h("option", { value: "xz" }, "XZ"), h("option", { value: "yz" }, "YZ"), h("option", { value: "zx" }, "ZX (lathe)"));
  const pageLabel = h("span", { class: "lbl" });
  const info = h("span", { class: "lbl", testid: "preview-info" });
  let page = 1;
  let pages = 1;

  let data: PreviewData | undefined;
  let prog: Segments | undefined, comp: Segments | undefined;
  let dots: { x: number; y: number; red: boolean }[] = [];
  let axisIdx: [number, number] = [0, 1];
  let view: View = { scale: 1, ox: 0, oy: 0 };
  let loadedFor = "";
  let tool: [number, number] | undefined;

  function planeAxes(names: string[]): [number, number] {
    const [hn, vn] = plane.value.toUpperCase().split("");
    return [names.indexOf(hn), names.indexOf(vn)];
  }

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
    const b: Box = bounds([prog, comp].filter((s): s is Segments => !!s));
    const w = stage.clientWidth || 800, hgt = stage.clientHeight || 600;
    const span = Math.max(b.maxX - b.minX, b.maxY - b.minY, 1e-3);
    const scale = 0.9 * Math.min(w / Math.max(b.maxX - b.minX, span * 0.05), hgt / Math.max(b.maxY - b.minY, span * 0.05));
    view = { scale, ox: w / 2 - scale * (b.minX + b.maxX) / 2, oy: hgt / 2 + scale * (b.minY + b.maxY) / 2 };
  }

  const sx = (x: number) => view.ox + view.scale * x;
  const sy = (y: number) => view.oy - view.scale * y;

  function strokePath(g: CanvasRenderingContext2D, s: Segments, color: string, width: number, rapidColor?: string): void {
    for (const wantRapid of rapidColor ? [0, 1] : [-1]) {
      g.beginPath();
      let lx = NaN, ly = NaN;
      for (let i = 0; i < s.count; i++) {
        if (wantRapid >= 0 && s.rapid[i] !== wantRapid) continue;
        const x0 = sx(s.xy[i * 4]), y0 = sy(s.xy[i * 4 + 1]);
        const x1 = sx(s.xy[i * 4 + 2]), y1 = sy(s.xy[i * 4 + 3]);
        if (Math.abs(x0 - lx) > 0.5 || Math.abs(y0 - ly) > 0.5) g.moveTo(x0, y0);
        else if (Math.abs(x1 - lx) < 0.7 && Math.abs(y1 - ly) < 0.7) continue; // under a pixel
        g.lineTo(x1, y1);
        lx = x1;
        ly = y1;
      }
      g.strokeStyle = wantRapid === 1 ? rapidColor! : color;
      g.lineWidth = width;
      g.setLineDash(wantRapid === 1 ? [6, 5] : []);
      g.stroke();
    }
    g.setLineDash([]);
  }

  function drawBase(): void {
    const g = size(base);
    if (!prog) return;
    strokePath(g, prog, COLORS.path, 1.5, COLORS.rapid);
    if (comp) strokePath(g, comp, COLORS.comp, 2);
    const seen = new Set<number>();
    let smooth = 0, red = 0;
    for (const redPass of [false, true]) {
      g.fillStyle = redPass ? COLORS.red : COLORS.smooth;
      for (const d of dots) {
        if (d.red !== redPass) continue;
        const x = sx(d.x), y = sy(d.y);
        const key = (Math.round(x / 2) << 16) ^ Math.round(y / 2) ^ (redPass ? 1 << 30 : 0);
        if (seen.has(key)) continue;
        seen.add(key);
        g.beginPath();
        g.arc(x, y, redPass ? 5 : 4, 0, 2 * Math.PI);
        g.fill();
        if (redPass) red++;
        else smooth++;
      }
    }
    stage.dataset.smoothDots = String(smooth);
    stage.dataset.redDots = String(red);
  }

  function drawTool(): void {
    const g = size(overlay);
    if (!tool || picture.hidden === false) return;
    const x = sx(tool[0]), y = sy(tool[1]);
    g.strokeStyle = COLORS.tool;
    g.lineWidth = 2;
    g.beginPath();
    g.arc(x, y, 9, 0, 2 * Math.PI);
    g.moveTo(x - 15, y); g.lineTo(x + 15, y);
    g.moveTo(x, y - 15); g.lineTo(x, y + 15);
    g.stroke();
  }

  function project(): void {
    if (!data) return;
    axisIdx = planeAxes(data.axes);
    const [a, b] = axisIdx;
    if (a < 0 || b < 0) {
      msg.err(`plane ${plane.value.toUpperCase()}: this machine has axes ${data.axes.join("")}`);
      prog = comp = undefined;
      dots = [];
    } else {
      prog = segments(data.programmed, a, b);
      // The tool-centre path where it leaves the programmed one (radius compensation on).
      const same = new Set(data.programmed.map((e) => `${e.startMm}|${e.endMm}`));
      const moved = data.compensated.filter((e) => !same.has(`${e.startMm}|${e.endMm}`));
      comp = moved.length ? segments(moved, a, b) : undefined;
      dots = data.junctions.map((j) => ({ x: j.positionMm[a], y: j.positionMm[b], red: j.class !== JunctionClass.SMOOTH }));
    }
    fit();
    drawBase();
    drawTool();
  }

  async function loadVelocity(): Promise<void> {
    const r = await preview.getPreview({ velocity: true, format: ImageFormat.SVG, page, widthPx: 1200, heightPx: 300 });
    velocity.src = URL.createObjectURL(new Blob([r.image as BlobPart], { type: "image/svg+xml" }));
    velocity.hidden = false;
  }

  async function loadPicture(): Promise<void> {
    const r = await preview.getPreview({
      format: ImageFormat.PNG, plane: plane.value === "zx" ? "xz" : plane.value, page,
      widthPx: Math.max(400, stage.clientWidth), heightPx: Math.max(300, stage.clientHeight),
    });
    pages = r.pages;
    picture.src = URL.createObjectURL(new Blob([r.image as BlobPart], { type: "image/png" }));
    picture.hidden = false;
    stage.dataset.smoothDots = String(r.smoothJunctions);
    stage.dataset.redDots = String(r.redJunctions);
  }

  async function load(s: Status): Promise<void> {
    loadedFor = `${s.program}/${s.blocksTotal}/${plane.value}/${page}`;
    stage.dataset.state = "loading";
    const t0 = performance.now();
    try {
      data = undefined; prog = comp = undefined; dots = [];
      velocity.hidden = true;
      if (s.blocksTotal <= DATA_MAX_BLOCKS) {
        picture.hidden = true;
        data = await preview.getPreviewData({ text: "", junctions: true });
        project();
        pages = 1;
      } else {
        size(base);
        await loadPicture();
      }
      stage.dataset.mode = data ? "data" : "picture";
      stage.dataset.state = "drawn";
      stage.dataset.ms = (performance.now() - t0).toFixed(0);
      setText(info, `${s.program}: ${s.blocksTotal} blocks${data ? "" : " (server picture of R387 page)"}`);
      setText(pageLabel, pages > 1 ? `page ${page}/${pages}` : "");
      msg.ok("");
      void loadVelocity().catch(() => {});
    } catch (e) {
      stage.dataset.state = "error";
      msg.err(errorText(e));
    }
  }

  let latest: Status | undefined;
  function reload(): void {
    if (latest && latest.program && !el.hidden) void load(latest);
  }

  subscribe((s) => {
    latest = s;
    const key = `${s.program}/${s.blocksTotal}/${plane.value}/${page}`;
    if (!el.hidden && s.program && key !== loadedFor && stage.dataset.state !== "loading") void load(s);
    if (!data || el.hidden) return;
    const [a, b] = axisIdx;
    const p: [number, number] = [s.axes[a]?.commandedMm ?? 0, s.axes[b]?.commandedMm ?? 0];
    if (!tool || p[0] !== tool[0] || p[1] !== tool[1]) {
      tool = p;
      drawTool();
    }
  });

  // Zoom and pan: wheel zooms about the pointer, a drag pans (mouse or one finger).
  function zoom(f: number, cx = stage.clientWidth / 2, cy = stage.clientHeight / 2): void {
    view = { scale: view.scale * f, ox: cx - (cx - view.ox) * f, oy: cy - (cy - view.oy) * f };
    drawBase();
    drawTool();
  }
  stage.addEventListener("wheel", (e) => {
    e.preventDefault();
    const r = stage.getBoundingClientRect();
    zoom(e.deltaY < 0 ? 1.25 : 0.8, e.clientX - r.left, e.clientY - r.top);
  }, { passive: false });
  let drag: { x: number; y: number } | undefined;
  stage.addEventListener("pointerdown", (e) => { drag = { x: e.clientX, y: e.clientY }; stage.setPointerCapture(e.pointerId); });
  stage.addEventListener("pointermove", (e) => {
    if (!drag) return;
    view.ox += e.clientX - drag.x;
    view.oy += e.clientY - drag.y;
    drag = { x: e.clientX, y: e.clientY };
    drawBase();
    drawTool();
  });
  for (const ev of ["pointerup", "pointercancel"]) stage.addEventListener(ev, () => (drag = undefined));
  plane.addEventListener("change", () => (data ? project() : reload()));
  new ResizeObserver(() => { if (data) { drawBase(); drawTool(); } }).observe(stage);

  const el = h("div", { class: "screen preview" },
    h("div", { class: "row" }, h("label", {}, "Plane ", plane),
      button("−", "preview-zoom-out", () => zoom(0.8), "", "observer"),
      button("+", "preview-zoom-in", () => zoom(1.25), "", "observer"),
      button("Fit", "preview-fit", () => { fit(); drawBase(); drawTool(); }, "", "observer"),
      button("◀", "preview-page-prev", () => { if (page > 1) { page--; reload(); } }, "", "observer"),
      pageLabel,
      button("▶", "preview-page-next", () => { if (page < pages) { page++; reload(); } }, "", "observer"),
      info),
    stage,
    h("div", { class: "legend" },
      h("span", { style: `color:${COLORS.path}` }, "— programmed"), h("span", { style: `color:${COLORS.rapid}` }, "- - rapid"),
      h("span", { style: `color:${COLORS.comp}` }, "— tool centre"), h("span", { style: `color:${COLORS.smooth}` }, "● smooth"),
      h("span", { style: `color:${COLORS.red}` }, "● stop / speed drop"), h("span", { style: `color:${COLORS.tool}` }, "⊕ tool")),
    velocity,
    msg.el);
  return { id: "preview", title: "Preview", el, onShow: () => requestAnimationFrame(() => (data ? (fit(), drawBase(), drawTool()) : reload())) };
}
