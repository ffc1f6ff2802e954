// Tiny DOM helpers: the HMI builds its screens from plain elements (no framework).

type Attrs = Record<string, string | number | boolean | undefined | EventListener>;
type Child = Node | string | null | undefined | false;

/** An element with attributes (`on*` keys are listeners, `testid` is `data-testid`). */
export function h<K extends keyof HTMLElementTagNameMap>(
  tag: K,
  attrs: Attrs = {},
  ...children: Child[]
): HTMLElementTagNameMap[K] {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === undefined || v === false) continue;
    if (k.startsWith("on") && typeof v === "function") {
      el.addEventListener(k.slice(2), v as EventListener);
    } else if (k === "testid") {
      el.dataset.testid = String(v);
    } else if (k === "class") {
      el.className = String(v);
    } else if (v === true) {
      el.setAttribute(k, "");
    } else {
      el.setAttribute(k, String(v));
    }
  }
  append(el, children);
  return el;
}

export function append(el: Element, children: Child[]): void {
  for (const c of children) {
    if (c === null || c === undefined || c === false) continue;
    el.append(typeof c === "string" ? document.createTextNode(c) : c);
  }
}

/** Replaces the children of `el`. */
export function fill(el: Element, ...children: Child[]): void {
  el.replaceChildren();
  append(el, children);
}

/** Sets text only when it changed (the DRO updates 25+ times a second). */
export function setText(el: Element, text: string): void {
  if (el.textContent !== text) el.textContent = text;
}

/** A button for the operator: `op` marks it as an active control observers cannot use. */
export function button(
  label: string,
  testid: string | undefined,
  onclick: () => void,
  cls = "",
  least: "operator" | "admin" | "observer" = "operator",
): HTMLButtonElement {
  const b = h("button", { testid, class: cls, type: "button" }, label);
  if (least !== "observer") b.dataset.least = least;
  b.addEventListener("click", () => {
    if (!b.disabled) onclick();
  });
  return b;
}
