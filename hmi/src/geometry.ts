// Preview geometry: PathElements flattened into polylines (arcs as chords), projected onto a
// view plane; kept as typed arrays so a large program costs little memory and draws fast.
import { type PathElement, PathKind } from "./gen/cnc/v1/cnc_pb";

/** Largest angle one chord of an arc spans. */
const ARC_STEP_RAD = Math.PI / 36;

/** Segments of a path in the view plane: x0 y0 x1 y1 per segment, and whether it is G0. */
export interface Segments {
  xy: Float32Array;
  rapid: Uint8Array;
  count: number;
}

/** Axis indices of an arc plane (kernel::block::Plane: G17 X→Y, G18 Z→X, G19 Y→Z). */
function arcAxes(plane: string): [number, number] {
  return plane === "G18" ? [2, 0] : plane === "G19" ? [1, 2] : [0, 1];
}

/** Points along one element (start excluded), each a full axis vector. */
function points(e: PathElement): number[][] {
  const isArc = e.kind === PathKind.ARC_CW || e.kind === PathKind.ARC_CCW;
  const [a, b] = arcAxes(e.plane);
  if (!isArc || e.centerMm.length <= Math.max(a, b)) return [e.endMm];
  const s = e.startMm, t = e.endMm, c = e.centerMm;
  const r = Math.hypot(s[a] - c[a], s[b] - c[b]);
  const a0 = Math.atan2(s[b] - c[b], s[a] - c[a]);
  let sweep = Math.atan2(t[b] - c[b], t[a] - c[a]) - a0;
  if (e.kind === PathKind.ARC_CCW) {
    if (sweep <= 1e-9) sweep += 2 * Math.PI;
  } else if (sweep >= -1e-9) sweep -= 2 * Math.PI;
  const n = Math.max(2, Math.ceil(Math.abs(sweep) / ARC_STEP_RAD));
  const out: number[][] = [];
  for (let i = 1; i <= n; i++) {
    const f = i / n;
    const p = s.map((v, k) => v + (t[k] - v) * f);
    p[a] = c[a] + r * Math.cos(a0 + sweep * f);
    p[b] = c[b] + r * Math.sin(a0 + sweep * f);
    out.push(p);
  }
  out[out.length - 1] = t;
  return out;
}

/** The elements as 2-D segments on axes (h, v). */
export function segments(els: PathElement[], h: number, v: number): Segments {
  let cap = els.length * 2 + 16;
  let xy = new Float32Array(cap * 4);
  let rapid = new Uint8Array(cap);
  let n = 0;
  for (const e of els) {
    let prev = e.startMm;
    for (const p of points(e)) {
      if (n === cap) {
        cap *= 2;
        const nxy = new Float32Array(cap * 4);
        nxy.set(xy);
        xy = nxy;
        const nr = new Uint8Array(cap);
        nr.set(rapid);
        rapid = nr;
      }
      xy.set([prev[h] ?? 0, prev[v] ?? 0, p[h] ?? 0, p[v] ?? 0], n * 4);
      rapid[n] = e.kind === PathKind.RAPID ? 1 : 0;
      prev = p;
      n++;
    }
  }
  return { xy, rapid, count: n };
}

export interface Box {
  minX: number;
  minY: number;
  maxX: number;
  maxY: number;
}

export function bounds(list: Segments[]): Box {
  const b = { minX: Infinity, minY: Infinity, maxX: -Infinity, maxY: -Infinity };
  for (const s of list) {
    for (let i = 0; i < s.count * 4; i += 2) {
      const x = s.xy[i], y = s.xy[i + 1];
      if (x < b.minX) b.minX = x;
      if (x > b.maxX) b.maxX = x;
      if (y < b.minY) b.minY = y;
      if (y > b.maxY) b.maxY = y;
    }
  }
  if (!isFinite(b.minX)) return { minX: -10, minY: -10, maxX: 10, maxY: 10 };
  return b;
}
