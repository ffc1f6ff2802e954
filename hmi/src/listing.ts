// A read-only program listing that stays fast for CAM-size texts: only the lines in view are
// in the DOM (fixed line height), the current line is highlighted and scrolled to.
import { h } from "./dom";

const LINE_PX = 30;
const OVERSCAN = 10;

export class Listing {
  readonly el: HTMLDivElement;
  private readonly spacer: HTMLDivElement;
  private readonly body: HTMLDivElement;
  private lines: string[] = [];
  private current = 0;

  constructor(testid?: string) {
    this.body = h("div", { class: "listing-body" });
    this.spacer = h("div", { class: "listing-spacer" }, this.body);
    this.el = h("div", { class: "listing", testid, translate: "no" }, this.spacer);
    this.el.addEventListener("scroll", () => this.draw());
    new ResizeObserver(() => this.draw()).observe(this.el);
  }

  setText(text: string): void {
    this.lines = text ? text.split(/\r?\n/) : [];
    if (this.lines.length > 1 && this.lines[this.lines.length - 1] === "") this.lines.pop();
    this.spacer.style.height = `${this.lines.length * LINE_PX}px`;
    this.draw();
  }

  /** Highlights 1-based `line` and scrolls it into the middle of the view. */
  goto(line: number, scroll = true): void {
    if (line === this.current && !scroll) return;
    this.current = line;
    if (scroll && line > 0) {
      const top = (line - 1) * LINE_PX - this.el.clientHeight / 2 + LINE_PX / 2;
      this.el.scrollTop = Math.max(0, top);
    }
    this.draw();
  }

  private draw(): void {
    const first = Math.max(0, Math.floor(this.el.scrollTop / LINE_PX) - OVERSCAN);
    const count = Math.ceil(this.el.clientHeight / LINE_PX) + 2 * OVERSCAN;
    const last = Math.min(this.lines.length, first + count);
    this.body.style.transform = `translateY(${first * LINE_PX}px)`;
    const rows: HTMLElement[] = [];
    for (let i = first; i < last; i++) {
      const n = i + 1;
      rows.push(
        h(
          "div",
          { class: n === this.current ? "ln cur" : "ln", "data-line": n },
          h("span", { class: "no" }, String(n)),
          this.lines[i],
        ),
      );
    }
    this.body.replaceChildren(...rows);
  }
}
