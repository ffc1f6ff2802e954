// The shell: header (connection, machine state, sign-in, role, STOP), tabs, the DRO panel and
// the screens; role gating of every active control; keyboard shortcuts.
import { ConnectError, Code } from "@connectrpc/connect";
import { machine } from "./api";
import { button, h, setText } from "./dom";
import { droPanel } from "./dro";
import { cycleBar } from "./cycle";
import { toolChangeDialog } from "./tool_change";
import { errorText, stateLabel, stateName } from "./format";
import { catalogues, lang, setLang, t } from "./i18n";
import type { Key } from "./lang/en";
import { alarmText } from "./server_text";
import { adoptFragmentToken, may, onRole, role, setRole, setToken, token, type Role } from "./session";
import { jogEnd } from "./jog";
import { drawn, onConnection, startStatus, subscribe } from "./status";
import type { Screen } from "./screen";
import { runScreen } from "./screens/run";
import { previewScreen } from "./screens/preview";
import { programsScreen } from "./screens/programs";
import { mdiScreen } from "./screens/mdi";
import { jogScreen } from "./screens/jog";
import { homingScreen } from "./screens/homing";
import { offsetsScreen } from "./screens/offsets";
import { constantsScreen } from "./screens/constants";
import { plcScreen } from "./screens/plc";
import { ioScreen } from "./screens/io";
import { alarmsScreen } from "./screens/alarms";

const flash = h("div", { class: "flash", testid: "flash" });
function say(text: string): void {
  flash.textContent = text;
  flash.classList.add("show");
  setTimeout(() => flash.classList.remove("show"), 5000);
}

async function stop(): Promise<void> {
  try {
    await machine.stop({});
  } catch (e) {
    say(errorText(e));
  }
}

async function hold(): Promise<void> {
  try {
    await machine.hold({});
  } catch (e) {
    say(errorText(e));
  }
}

/** Asks the server who we are; a refused token is dropped (the page is an observer again). */
async function whoAmI(msg?: HTMLElement): Promise<void> {
  try {
    const me = await machine.whoAmI({});
    setRole(me.role);
    if (msg) msg.textContent = me.who === "local" ? "" : t("login.as", { who: me.who });
  } catch (e) {
    if (e instanceof ConnectError && e.code === Code.Unauthenticated) {
      setToken("");
      if (msg) msg.textContent = t("login.refused");
      return whoAmI();
    }
    setRole("observer");
    if (msg) msg.textContent = errorText(e);
  }
}

function header(): HTMLElement {
  const conn = h("span", { class: "conn connecting", testid: "connection-state", "data-state": "connecting" }, t("conn.connecting"));
  const state = h("span", { class: "state", testid: "machine-state" }, "—");
  const roleEl = h("span", { class: "role", testid: "role", "data-role": "observer" }, t("role.observer"));
  const who = h("span", { class: "who" });
  const tokenIn = h("input", {
    type: "password",
    testid: "login-token",
    placeholder: t("login.placeholder"),
    autocomplete: "off",
    class: "token",
  });
  const submit = button(
    t("login.submit"),
    "login-submit",
    () => {
      setToken(tokenIn.value.trim());
      tokenIn.value = "";
      void whoAmI(who);
    },
    "",
    "observer",
  );
  tokenIn.addEventListener("keydown", (e) => {
    if (e.key === "Enter") submit.click();
  });
  const signOut = button(t("login.out"), "logout", () => {
    setToken("");
    void whoAmI(who);
  }, "", "observer");
  const alarm = h("span", { class: "alarm-banner", testid: "alarm-banner" });
  const stopBtn = button(t("stop"), "stop", () => void stop(), "stop");
  // The other language, one tap away (the page loads again in it).
  const langBtn = button(t("lang.other"), "lang-switch", () => setLang(lang() === "cs" ? "en" : "cs"), "lang", "observer");
  langBtn.title = t("lang.otherName");

  onConnection((c) => {
    conn.className = `conn ${c}`;
    conn.dataset.state = c;
    setText(conn, t(c === "live" ? "conn.live" : c === "lost" ? "conn.lost" : "conn.connecting"));
    state.classList.toggle("stale", c !== "live");
  });
  subscribe((s) => {
    setText(state, stateLabel(s.state));
    state.dataset.state = stateName(s.state);
    setText(alarm, s.activeAlarms.length ? `⚠ ${alarmText(s.activeAlarms[0].message)}` : "");
  });
  const signin = h("span", { class: "signin" }, tokenIn, submit, signOut, who, roleEl);
  onRole((r: Role) => {
    setText(roleEl, t(`role.${r}`));
    roleEl.dataset.role = r;
    // Signed in with a token: the field gives way to "Sign out" (the header stays one line).
    signin.classList.toggle("signed", token() !== "");
  });
  return h(
    "header",
    {},
    h("span", { class: "brand" }, "cnc"),
    conn,
    state,
    alarm,
    h("span", { class: "grow" }),
    signin,
    langBtn,
    stopBtn,
  );
}

/** Disables every active control the role may not use (observers: none at all). */
function gate(root: Element): void {
  const els = [...root.querySelectorAll<HTMLElement>("[data-least]")];
  if (root instanceof HTMLElement && root.dataset.least) els.push(root);
  els.forEach((el) => {
    const ok = may(el.dataset.least as Role);
    (el as HTMLButtonElement).disabled = !ok;
  });
}

function shortcuts(): void {
  window.addEventListener(
    "keydown",
    (e) => {
      if (e.key === "Escape") {
        e.preventDefault();
        void stop();
        return;
      }
      const t = e.target as HTMLElement;
      const typing = t.matches("input:not([type=range]):not([type=checkbox]), textarea, select");
      // Space is feed hold anywhere but in a text field (and never "clicks" a focused button).
      if (e.key === " " && !typing) {
        e.preventDefault();
        if (may("operator")) void hold();
      }
    },
    true,
  );
  // A focused button would "click" on the space key's release: not here (space is hold).
  window.addEventListener(
    "keyup",
    (e) => {
      const t = e.target as HTMLElement;
      if (e.key === " " && !t.matches("input:not([type=range]):not([type=checkbox]), textarea, select")) e.preventDefault();
    },
    true,
  );
}

function boot(): void {
  document.documentElement.lang = lang();
  adoptFragmentToken();
  const screens: Screen[] = [
    runScreen(),
    previewScreen(),
    programsScreen(),
    mdiScreen(),
    jogScreen(),
    homingScreen(),
    offsetsScreen(),
    constantsScreen(),
    plcScreen(),
    ioScreen(),
    alarmsScreen(),
  ];
  const nav = h("nav", {});
  const view = h("section", { class: "view" });
  const app = h("div", { class: "app" });
  const tabs = new Map<string, HTMLButtonElement>();
  function show(id: string): void {
    for (const s of screens) {
      const on = s.id === id;
      s.el.hidden = !on;
      tabs.get(s.id)!.classList.toggle("on", on);
      if (on) app.dataset.screen = id;
      if (on) s.onShow?.();
    }
    history.replaceState(null, "", `#${id}`);
  }
  for (const s of screens) {
    // A full and a short label: CSS shows the one that fits the panel's width.
    const long = t(`tab.${s.id}` as Key), short = t(`tab.${s.id}.short` as Key);
    const tab = h("button", { class: "tab", testid: `tab-${s.id}`, type: "button", title: long },
      h("span", { class: "long" }, long), h("span", { class: "short" }, short));
    tab.addEventListener("click", () => show(s.id));
    tabs.set(s.id, tab);
    nav.append(tab);
    view.append(s.el);
  }
  // The cycle bar under the screen, shown on the screens that run the machine (CSS by
  // data-screen), never scrolled away with the screen's content.
  const work = h("div", { class: "work" }, view, cycleBar(say));
  app.append(header(), nav, h("main", {}, droPanel(), work), flash, toolChangeDialog(say));
  document.body.append(app);
  new MutationObserver((records) => {
    for (const r of records) r.addedNodes.forEach((n) => n instanceof Element && gate(n));
  }).observe(app, { childList: true, subtree: true });
  onRole(() => gate(app));
  gate(app);
  shortcuts();
  const first = location.hash.slice(1);
  show(screens.some((s) => s.id === first) ? first : "run");
  startStatus();
  void whoAmI();
  // A kiosk may be sent to `#token=…` on an open page (no reload): sign in then too.
  window.addEventListener("hashchange", () => {
    if (adoptFragmentToken()) {
      show("run");
      void whoAmI();
    }
  });
  // For integrators' tests and the benchmark: role, and when snapshots reached the screen.
  (window as unknown as { cncHmi: object }).cncHmi = { drawn, role, jogEnd, lang, catalogues };
}

boot();
