// The cycle controls (start, hold, resume, reset, single block, optional stop) as one bar the
// shell keeps at the bottom of the Run, Jog and MDI screens: on a small panel they must stay
// in view whatever the screen above them holds (the screen scrolls, the bar does not).
import { machine } from "./api";
import { button, h } from "./dom";
import { errorText } from "./format";
import { t } from "./i18n";
import { subscribe } from "./status";

export function cycleBar(report: (text: string) => void): HTMLElement {
  const call = (f: () => Promise<unknown>) => () => {
    f().catch((e) => report(errorText(e)));
  };
  const single = button(t("cycle.single"), "single-block", () =>
    call(() => machine.setSingleBlock({ enabled: !single.classList.contains("active") }))(),
  "toggle");
  const optStop = button(t("cycle.optStop"), "optional-stop", () =>
    call(() => machine.setOptionalStop({ on: !optStop.classList.contains("active") }))(),
  "toggle");
  subscribe((s) => {
    single.classList.toggle("active", s.singleBlock);
    optStop.classList.toggle("active", s.optionalStop);
  });
  return h(
    "div",
    { class: "cycle", testid: "cycle-bar" },
    button(t("cycle.start"), "cycle-start", call(() => machine.start({})), "start"),
    button(t("cycle.hold"), "feed-hold", call(() => machine.hold({})), "hold"),
    button(t("cycle.resume"), "resume", call(() => machine.resume({})), "resume"),
    button(t("cycle.reset"), "reset", call(() => machine.reset({})), "reset"),
    single,
    optStop,
  );
}
