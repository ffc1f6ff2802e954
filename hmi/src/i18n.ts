// The screen's language: Czech or English, from the browser's language unless the operator
// chose one on the screen (kept in localStorage). Every text the page writes comes from a
// catalogue (lang/en.ts, lang/cs.ts) through t(); the daemon's texts are matched by their
// stable codes (lang/diagnostics_cs.ts, lang/alarms_cs.ts), never by their wording.
import { en, type Key } from "./lang/en";
import { cs } from "./lang/cs";

export type Lang = "en" | "cs";
const KEY = "cnc.lang";
const TABLES: Record<Lang, Record<Key, string>> = { en, cs };

function initial(): Lang {
  const saved = localStorage.getItem(KEY);
  if (saved === "en" || saved === "cs") return saved;
  // Any Czech locale (cs, cs-CZ) reads Czech; every other browser reads English.
  const langs = navigator.languages?.length ? navigator.languages : [navigator.language];
  return langs[0]?.toLowerCase().startsWith("cs") ? "cs" : "en";
}

const current: Lang = initial();

export function lang(): Lang {
  return current;
}

/** The text of `key` in the screen's language, `{name}` replaced from `vars`. */
export function t(key: Key, vars: Record<string, string | number> = {}): string {
  const s = TABLES[current][key] ?? en[key];
  return s.replace(/\{(\w+)\}/g, (m, k: string) => (k in vars ? String(vars[k]) : m));
}

/** Switches the language. The page loads again in it: every screen is built in one language
 * (simpler and safer than re-labelling live screens); the token (sessionStorage) and the
 * screen shown (the address's #fragment) survive the reload. */
export function setLang(l: Lang): void {
  localStorage.setItem(KEY, l);
  location.reload();
}

/** For the browser suite: both catalogues, to find English left on a Czech screen. */
export const catalogues = TABLES;
