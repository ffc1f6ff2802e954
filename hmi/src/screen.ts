// What every screen gives the shell.
export interface Screen {
  /** Short id (the tab's test id is `tab-<id>`). */
  id: string;
  /** The tab's label: catalogue keys `tab.<id>` and `tab.<id>.short`. */
  el: HTMLElement;
  /** Called when the screen comes into view (refresh lists). */
  onShow?(): void;
}

/** A message line under a screen's controls: errors stay until the next action. */
export function messageLine(): { el: HTMLElement; ok(t: string): void; err(t: string): void } {
  const el = document.createElement("div");
  el.className = "msg";
  el.dataset.testid = "message";
  return {
    el,
    ok(t: string) {
      el.className = "msg ok";
      el.textContent = t;
    },
    err(t: string) {
      el.className = "msg err";
      el.textContent = t;
    },
  };
}
