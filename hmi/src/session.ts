// Who is signed in: the token (typed in, or `#token=…` in the URL for a kiosk screen, kept in
// sessionStorage and removed from the address bar) and the role the server resolved (WhoAmI).

const KEY = "cnc.token";

export type Role = "observer" | "operator" | "admin";
const RANK: Record<Role, number> = { observer: 0, operator: 1, admin: 2 };

let current: Role = "observer";
const listeners: Array<(r: Role) => void> = [];

export function token(): string {
  return sessionStorage.getItem(KEY) ?? "";
}

export function setToken(t: string): void {
  if (t) sessionStorage.setItem(KEY, t);
  else sessionStorage.removeItem(KEY);
}

/** Takes `#token=…` from the address, keeps it for this tab and clears it from the bar;
 * true when there was one. */
export function adoptFragmentToken(): boolean {
  const m = /(?:^#|&)token=([^&]*)/.exec(location.hash);
  if (!m) return false;
  setToken(decodeURIComponent(m[1]));
  history.replaceState(null, "", location.pathname + location.search);
  return true;
}

export function role(): Role {
  return current;
}

export function setRole(r: string): void {
  current = r === "admin" || r === "operator" ? r : "observer";
  for (const f of listeners) f(current);
}

export function onRole(f: (r: Role) => void): void {
  listeners.push(f);
}

/** The caller's role is at least `least`. */
export function may(least: Role): boolean {
  return RANK[current] >= RANK[least];
}
