// Continuous jog from a browser: a JogLease renewed every RENEW_MS while the button is held.
// The axis stops when the button is released, the pointer leaves or is cancelled, the page
// loses focus or visibility, the status stream drops (JogStop), and in any case when the
// renewals stop arriving (the lease lapses in cncd after LEASE_MS).
import { machine } from "./api";
import { errorText } from "./format";
import { onConnection } from "./status";

const RENEW_MS = 100;
const LEASE_MS = 400;

let timer: number | undefined;
let active: { axis: string; direction: number } | undefined;
let report: (msg: string) => void = () => {};

export function onJogError(f: (msg: string) => void): void {
  report = f;
}

export function jogging(): boolean {
  return active !== undefined;
}

async function renew(axis: string, direction: number, speed: number): Promise<void> {
  try {
    await machine.jogLease({ axis, direction, speedMmMin: speed, leaseMs: LEASE_MS });
  } catch (e) {
    // A refused renewal ends the jog here too (the server lets the lease lapse anyway).
    if (active) report(errorText(e));
    release("refused");
  }
}

/** Starts a continuous jog of `axis` in `direction` (+1/-1) at `speed` mm/min. */
export function press(axis: string, direction: number, speed: number): void {
  if (active) release();
  active = { axis, direction };
  void renew(axis, direction, speed);
  timer = window.setInterval(() => {
    if (active) void renew(axis, direction, speed);
  }, RENEW_MS);
}

/** Why the last continuous jog ended (integrators' tests read it: `cncHmi.jogEnd()`). */
let endReason = "";
export function jogEnd(): string {
  return endReason;
}

/** Ends a continuous jog (a no-op when none runs). */
export function release(reason = "release"): void {
  if (timer !== undefined) window.clearInterval(timer);
  timer = undefined;
  if (!active) return;
  active = undefined;
  endReason = reason;
  machine.jogStop({}).catch(() => {
    // Connection gone: the lease lapses in cncd.
  });
}

/** Binds a button to hold-to-jog: any way the press can end stops the axis. No pointer
 * capture: a finger sliding off the button stops the axis (pointerleave). `start` returns
 * false when the press is not a continuous jog (step mode). */
export function holdToJog(el: HTMLButtonElement, start: () => boolean): void {
  el.addEventListener("pointerdown", (ev) => {
    if (el.disabled || ev.button > 0) return;
    if (start()) el.classList.add("held");
  });
  for (const ev of ["pointerup", "pointercancel", "pointerleave"]) {
    el.addEventListener(ev, () => {
      el.classList.remove("held");
      if (jogging()) release(`${ev}`);
    });
  }
  el.addEventListener("contextmenu", (ev) => ev.preventDefault());
}

window.addEventListener("blur", () => release("blur"));
document.addEventListener("visibilitychange", () => {
  if (document.visibilityState !== "visible") release("hidden");
});
window.addEventListener("pagehide", () => release("hidden"));
onConnection((c) => {
  if (c !== "live") release("connection");
});
