// The status stream: one StreamStatus call kept open with reconnect and backoff. The screen
// never shows stale numbers as live: when no snapshot arrives for STALL_MS the connection is
// "lost", the DRO greys out and the stream is opened again.
import type { Status } from "./gen/cnc/v1/cnc_pb";
import { machine } from "./api";

export type Conn = "connecting" | "live" | "lost";

/** Snapshots per second asked of the server (the DRO goal is 25 Hz or more). */
export const RATE_HZ = 30;
/** No snapshot for this long: the numbers on screen are no longer live. */
const STALL_MS = 1000;
const BACKOFF_MIN_MS = 250;
/** Snapshots read from one stream before it is replaced by a fresh one (2 minutes at
 * RATE_HZ). @connectrpc/connect 2.3.0 races every read of a server stream against a promise
 * that settles only when the call ends (run-call.js), so each snapshot leaves a few hundred
 * bytes reachable until then: an open stream would grow the page about 10 MB an hour. */
const RECYCLE_AFTER = 120 * RATE_HZ;
const BACKOFF_MAX_MS = 4000;

let conn: Conn = "connecting";
let latest: Status | undefined;
let lastAt = 0;
let abort: AbortController | undefined;
const onStatus: Array<(s: Status) => void> = [];
const onConn: Array<(c: Conn) => void> = [];

export function status(): Status | undefined {
  return conn === "live" ? latest : undefined;
}
export function connection(): Conn {
  return conn;
}
export function subscribe(f: (s: Status) => void): void {
  onStatus.push(f);
}
export function onConnection(f: (c: Conn) => void): void {
  onConn.push(f);
}

function setConn(c: Conn): void {
  if (c === conn) return;
  conn = c;
  for (const f of onConn) f(c);
}

const sleep = (ms: number) => new Promise((r) => setTimeout(r, ms));

async function run(): Promise<void> {
  let backoff = BACKOFF_MIN_MS;
  for (;;) {
    abort = new AbortController();
    let read = 0;
    try {
      for await (const s of machine.streamStatus({ rateHz: RATE_HZ }, { signal: abort.signal })) {
        lastAt = performance.now();
        backoff = BACKOFF_MIN_MS;
        latest = s;
        setConn("live");
        schedule();
        if (++read >= RECYCLE_AFTER) break;
      }
    } catch {
      // Refused, cut or aborted by the stall watch: reconnect below.
    }
    // Recycled (see RECYCLE_AFTER): the call ends (break cancels it), a new one opens at
    // once; the screen stays live (the next snapshot comes within the stall time).
    if (read >= RECYCLE_AFTER) {
      abort.abort();
      continue;
    }
    // Stays "lost" (not "connecting") until a fresh snapshot arrives: the operator must see it.
    setConn("lost");
    await sleep(backoff);
    backoff = Math.min(backoff * 2, BACKOFF_MAX_MS);
  }
}

// Screens draw the newest snapshot once per animation frame (a burst of snapshots draws once).
let pending = false;
function schedule(): void {
  if (pending) return;
  pending = true;
  requestAnimationFrame(() => {
    pending = false;
    if (conn !== "live" || !latest) return;
    for (const f of onStatus) f(latest);
    probe(latest);
  });
}

/** What the benchmark reads: when each snapshot sequence reached the screen (epoch ms). */
export const drawn: Array<[number, number]> = [];
function probe(s: Status): void {
  drawn.push([Number(s.sequence), performance.timeOrigin + performance.now()]);
  if (drawn.length > 20000) drawn.splice(0, 10000);
}

export function startStatus(): void {
  setInterval(() => {
    if (conn === "live" && performance.now() - lastAt > STALL_MS) {
      setConn("lost");
      abort?.abort();
    }
  }, 200);
  void run();
}
