// The velocity plot in the screen's colours and language. cncd draws its SVG for paper (white
// ground, dark ink, English titles: the same picture `cncctl preview` writes to a file); the
// page recolours it for the dark screen and puts its fixed titles in the catalogue's words.
import { t } from "./i18n";

function rgb(hex: string): [number, number, number] | undefined {
  const m = /^#([0-9a-f]{2})([0-9a-f]{2})([0-9a-f]{2})$/i.exec(hex.trim());
  return m ? [parseInt(m[1], 16), parseInt(m[2], 16), parseInt(m[3], 16)] : undefined;
}

function hex(c: number[]): string {
  return `#${c.map((v) => Math.round(Math.max(0, Math.min(255, v))).toString(16).padStart(2, "0")).join("")}`;
}

/** A paper colour for the dark screen: greys turn over (white ground → dark, black ink →
 * light, light grid → dim), coloured ink keeps its hue and is lifted to read on dark. */
export function onDark(color: string, ground: string): string {
  const c = rgb(color);
  if (!c) return color;
  const max = Math.max(...c), min = Math.min(...c);
  if (max - min < 40) {
    if (min >= 250) return ground;
    // Grey level g on paper becomes 235 - 0.75 g: black ink 235, the grid (225) 66.
    const g = 235 - 0.75 * ((max + min) / 2);
    return hex([g, g + 2, g + 4]);
  }
  const lift = Math.max(0, 170 - max);
  return hex(c.map((v) => v + lift + 0.25 * (255 - v - lift)));
}

/** The SVG of a velocity plot, recoloured and with its titles translated. */
export function darkPlot(svg: string): string {
  const doc = new DOMParser().parseFromString(svg, "image/svg+xml");
  const root = doc.documentElement;
  if (root.nodeName !== "svg") return svg;
  const css = getComputedStyle(document.documentElement);
  const ground = css.getPropertyValue("--panel").trim() || "#1b2024";
  for (const el of Array.from(root.querySelectorAll("[fill], [stroke]"))) {
    for (const a of ["fill", "stroke"]) {
      const v = el.getAttribute(a);
      if (v && v.startsWith("#")) el.setAttribute(a, onDark(v, ground));
    }
  }
  // A ground even where the picture leaves it open.
  root.setAttribute("style", `background:${ground}`);
  const words: Record<string, string> = {
    "time s": t("plot.time"),
    "speed mm/min": t("plot.speed"),
    "axis acceleration mm/s²": t("plot.accel"),
    "path speed": t("plot.pathSpeed"),
    "programmed feed (G0: rapid speed)": t("plot.feed"),
    "block boundary": t("plot.boundary"),
    "boundary after a red junction": t("plot.redBoundary"),
  };
  for (const el of Array.from(root.querySelectorAll("text"))) {
    const s = el.textContent ?? "";
    const title = /^Velocity over time\s+page (\d+) of (\d+)\s+(\S+) s \.\. (\S+) s$/.exec(s);
    if (title) el.textContent = t("plot.title", { page: title[1], pages: title[2], from: title[3], to: title[4] });
    else if (words[s]) el.textContent = words[s];
  }
  return new XMLSerializer().serializeToString(doc);
}
