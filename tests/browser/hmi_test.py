"""The browser HMI in real headless Chromium (issue #30), driven through its data-testid
attributes against a cncd on the simulated machine. Environment: CNC_HMI_URL (cncd's HMI
origin), CNC_TOKEN (an operator token), CNC_ADMIN_TOKEN (an admin token: the I/O tests),
CNC_SHOTS (folder for the Run and Preview screenshots), CNC_FAIL_SHOTS (failure screenshots and
the 800 x 480 ones of the I/O and Constants screens). Every wait is on a condition with a generous timeout (a loaded machine is
slow), never a sleep and an assert. Prints one line per test and "N passed, M failed"."""

import os
import re
import struct
import sys
import tempfile
import time
import traceback
import urllib.request
from urllib.parse import urlparse

from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.actions.wheel_input import ScrollOrigin
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys
from selenium.webdriver.support.ui import Select

from chromium import browser, viewport
from proxy import CuttableProxy

PATIENCE_S = 60.0
TOKEN = os.environ["CNC_TOKEN"]
ADMIN_TOKEN = os.environ["CNC_ADMIN_TOKEN"]
SHOTS = os.environ.get("CNC_SHOTS", "")
target = urlparse(os.environ["CNC_HMI_URL"])
PROXY = CuttableProxy(target.hostname, target.port)
URL = f"http://127.0.0.1:{PROXY.port}/"

# The way back to the start is G1 at 50 mm/s: a rapid would fault over the 5 mm following
# window (that is the alarm test). A continuous path (G23) under radius compensation (G41,
# tool D1 of radius 3 mm: the tool-centre path is drawn blue beside the programmed one):
# lines with shallow bends (smooth junctions, yellow), two square corners (stops, red) and an
# arc joined tangentially; about 20 s at F600, long enough to hold, resume and stop.
PROGRAM = """N10 G1 X0 Y0 F3000
N12 G92 D1 R0=3.0
N14 G17 D1
N20 G41 G23 G1 X20 Y1 F600
N30 X40 Y3
N40 X60 Y6
N50 X60 Y30
N60 G3 X40 Y50 I-20 J0
N70 G1 X0 Y50
N80 X0 Y0
N90 G40 G1 X0 Y-5
"""


def wait(what, cond, timeout=PATIENCE_S):
    """Polls cond() until it returns a truthy value; fails naming `what`."""
    end = time.monotonic() + timeout
    last = None
    while time.monotonic() < end:
        try:
            v = cond()
            if v:
                return v
        except Exception as e:  # element not there yet, stale, ...
            last = e
        time.sleep(0.05)
    what = what() if callable(what) else what
    raise AssertionError(f"timed out waiting for {what}" + (f" ({last})" if last else ""))


class Page:
    def __init__(self, d):
        self.d = d

    def el(self, tid: str):
        return self.d.find_element(By.CSS_SELECTOR, f'[data-testid="{tid}"]')

    def text(self, tid: str) -> str:
        # textContent: what the page wrote (CSS may upper-case it; hidden screens have text).
        return (self.el(tid).get_attribute("textContent") or "").strip()

    def tab(self, name: str) -> None:
        self.el(f"tab-{name}").click()

    def x(self) -> float:
        return float(self.text("dro-X"))

    def state(self) -> str:
        # data-state: the state's stable name whatever the screen's language.
        return self.el("machine-state").get_attribute("data-state") or ""

    def wait_state(self, *states: str, timeout=PATIENCE_S) -> str:
        return wait(lambda: f"machine state in {states} (now {self.state()})",
                    lambda: self.state() in states and self.state(), timeout)

    def wait_live(self) -> None:
        wait("connection-state live", lambda: self.el("connection-state").get_attribute("data-state") == "live")

    def wait_x_at_rest(self) -> float:
        """X once the machine is idle and two reads half a second apart agree."""
        self.wait_state("IDLE")

        def steady():
            a = self.x()
            time.sleep(0.5)
            return self.state() == "IDLE" and abs(self.x() - a) < 1e-9 and (a,)
        return wait("X at rest", steady)[0]

    def sign_in(self, token: str) -> None:
        self.el("login-token").send_keys(token)
        self.el("login-submit").click()

    def shot(self, name: str, folder: str = SHOTS) -> None:
        if folder:
            self.d.save_screenshot(os.path.join(folder, name))


results = []
# Run a subset while working on one: CNC_TESTS=word,word runs the tests whose names hold one.
ONLY = [x for x in os.environ.get("CNC_TESTS", "").split(",") if x]


def test(fn):
    results.append(fn)
    return fn


op = Page(browser())
obs = Page(browser())


@test
def observer_by_default_sees_everything_but_cannot_press():
    obs.d.get(URL)
    obs.wait_live()
    wait("role observer", lambda: obs.text("role") == "observer")
    for tid in ("cycle-start", "feed-hold", "resume", "stop", "reset", "mdi-send", "program-select",
                "home-all", "jog-X-plus", "feed-override", "mdi-input", "program-upload",
                "probe-jog-start", "probe-offsets-start", "probe-offsets-kind", "probe-offsets-entry"):
        el = wait(f"{tid} present", lambda: obs.el(tid))
        assert not el.is_enabled(), f"{tid} is enabled for an observer"
    state = obs.state()
    ActionChains(obs.d).move_to_element(obs.el("cycle-start")).click().perform()
    assert obs.state() == state


@test
def sign_in_with_a_wrong_token_is_refused_then_operator():
    op.d.get(URL)
    op.wait_live()
    op.sign_in("not-a-token")
    wait("token refused", lambda: "refused" in op.d.find_element(By.CSS_SELECTOR, ".who").text)
    assert op.text("role") == "observer"
    op.sign_in(TOKEN)
    wait("role operator", lambda: op.text("role") == "operator")
    wait("cycle start enabled", lambda: op.el("cycle-start").is_enabled())
    wait("dro-X shows mm", lambda: op.text("dro-X").replace("-", "").replace(".", "").isdigit())


@test
def upload_select_and_preview_with_junction_dots():
    path = os.path.join(tempfile.mkdtemp(), "hmi_test.nc")
    with open(path, "w") as f:
        f.write(PROGRAM)
    op.tab("programs")
    op.el("program-upload").send_keys(path)
    row = wait("uploaded program in the list", lambda: op.d.find_element(
        By.CSS_SELECTOR, '[data-testid="program-list"] tr[data-name="hmi_test.nc"]'))
    row.click()
    op.el("program-select").click()
    wait("program selected", lambda: op.d.execute_script(
        "return document.querySelector('[data-testid=program-name]').textContent") == "hmi_test.nc")
    op.tab("preview")
    stage = op.el("preview")
    wait("preview drawn", lambda: stage.get_attribute("data-state") == "drawn")
    smooth = int(stage.get_attribute("data-smooth-dots") or 0)
    red = int(stage.get_attribute("data-red-dots") or 0)
    assert smooth > 0 and red > 0, f"junction dots: {smooth} smooth, {red} red"
    # The pixels themselves: yellow and red dots and the path are on the canvas.
    counts = op.d.execute_script("""
        const c = arguments[0].querySelector('canvas');
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let yellow = 0, red = 0, grey = 0;
        for (let i = 0; i < d.length; i += 4) {
          const [r, g, b, a] = [d[i], d[i+1], d[i+2], d[i+3]];
          if (a < 200) continue;
          if (r > 220 && g > 190 && b < 80) yellow++;
          else if (r > 220 && g < 80 && b < 80) red++;
          else if (r > 150 && Math.abs(r - g) < 12 && Math.abs(g - b) < 12) grey++;
        }
        return [yellow, red, grey];""", stage)
    assert all(n > 20 for n in counts), f"yellow, red, path pixels: {counts}"
    # The tool-centre path of G41 (blue) beside the programmed one.
    blue = op.d.execute_script("""
        const c = arguments[0].querySelector('canvas');
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let n = 0;
        for (let i = 0; i < d.length; i += 4) if (d[i+3] > 200 && d[i+2] > 200 && d[i] < 100) n++;
        return n;""", stage)
    assert blue > 100, f"tool-centre (blue) pixels: {blue}"


def touch(d, kind, points):
    d.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": kind, "touchPoints": [
        {"x": x, "y": y, "id": i, "radiusX": 5, "radiusY": 5, "force": 1} for i, (x, y) in points]})


@test
def preview_pinch_and_wheel_zoom_and_the_zoomed_extent_is_refined():
    stage = op.el("preview")
    scale = lambda: float(stage.get_attribute("data-scale"))
    s0 = scale()
    r = op.d.execute_script("const r = arguments[0].getBoundingClientRect();"
                            "return [r.left + r.width / 2, r.top + r.height / 2];", stage)
    cx, cy = r
    # Two fingers moving apart (touch events through the DevTools protocol: the page sees
    # pointer events of type touch): zoom in about their middle.
    op.d.execute_cdp_cmd("Emulation.setTouchEmulationEnabled", {"enabled": True, "maxTouchPoints": 5})
    touch(op.d, "touchStart", [(0, (cx - 40, cy)), (1, (cx + 40, cy))])
    for k in range(1, 6):
        touch(op.d, "touchMove", [(0, (cx - 40 - 20 * k, cy)), (1, (cx + 40 + 20 * k, cy))])
    touch(op.d, "touchEnd", [])
    op.d.execute_cdp_cmd("Emulation.setTouchEmulationEnabled", {"enabled": False})
    s1 = wait("pinch zoomed in", lambda: scale() > s0 * 2 and scale())
    # The server's outline of the extent shown comes after the zoom, finer.
    wait("zoomed extent drawn", lambda: stage.get_attribute("data-detail") == "extent")
    # The wheel zooms out about the pointer; Fit shows the whole program again.
    ActionChains(op.d).scroll_from_origin(ScrollOrigin.from_element(stage), 0, 200).perform()
    wait("wheel zoomed out", lambda: scale() < s1)
    op.el("preview-fit").click()
    wait("the whole program again", lambda: scale() < s1 / 2 and stage.get_attribute("data-detail") == "whole")


@test
def a_refused_upload_lists_coded_diagnostics_that_link_to_the_line():
    path = os.path.join(tempfile.mkdtemp(), "hmi_bad.nc")
    with open(path, "w") as f:
        f.write("N10 G1 X10 F500\nN20 G1 X20\nN30 G1 X0 Y0 Q7\n")
    op.tab("programs")
    op.el("program-upload").send_keys(path)
    link = wait("a diagnostic", lambda: op.d.find_element(
        By.CSS_SELECTOR, '[data-testid="diagnostics"] a[data-line="3"]'))
    assert "[unknown_address] line 3:14" in link.text, link.text
    link.click()
    wait("listing at line 3", lambda: op.d.find_element(
        By.CSS_SELECTOR, '[data-testid="program-listing"] .ln.cur').get_attribute("data-line") == "3")
    assert not op.d.find_elements(By.CSS_SELECTOR, '[data-testid="program-list"] tr[data-name="hmi_bad.nc"]')


@test
def cycle_start_moves_x_on_the_run_screen():
    op.tab("run")
    x0 = op.wait_x_at_rest()
    op.el("cycle-start").click()
    op.wait_state("RUNNING")
    wait("dro-X changes", lambda: abs(op.x() - x0) > 1.0)
    line = wait("current line highlighted", lambda: op.d.find_element(
        By.CSS_SELECTOR, '[data-testid="run-listing"] .ln.cur').get_attribute("data-line"))
    assert int(line) >= 1
    wait("X past 30 mm", lambda: op.x() > 30.0)
    op.shot("hmi_run.png")


@test
def feed_hold_stops_and_resume_continues():
    op.el("feed-hold").click()
    op.wait_state("HOLD")

    def held_still():
        a = op.x()
        time.sleep(0.4)
        return op.state() == "HOLD" and op.x() == a and (a,)
    x_held = wait("X still in hold", held_still)[0]
    op.el("resume").click()
    op.wait_state("RUNNING")
    wait("X moves again", lambda: op.x() != x_held)
    op.tab("preview")
    wait("live tool drawn", lambda: op.el("preview").get_attribute("data-state") == "drawn")
    wait("tool past the arc", lambda: float(op.text("dro-Y")) > 40.0)
    op.shot("hmi_preview.png")
    op.tab("run")


@test
def stop_ends_the_program():
    op.el("stop").click()
    op.wait_x_at_rest()


@test
def the_preview_draws_the_restart_approach_after_a_stop():
    # The stop ended the program early: status names the block to restart from, and the
    # preview draws the approach to it (magenta, dashed) apart from the program's paths.
    op.tab("preview")
    stage = op.el("preview")
    wait("approach drawn", lambda: int(stage.get_attribute("data-approach-points") or 0) >= 2)
    op.tab("run")


@test
def space_holds_and_escape_stops():
    op.el("cycle-start").click()
    op.wait_state("RUNNING")
    # The focus is on the Cycle start button just clicked: space must hold, not press it.
    ActionChains(op.d).send_keys(Keys.SPACE).perform()
    op.wait_state("HOLD")
    ActionChains(op.d).send_keys(Keys.ESCAPE).perform()
    op.wait_x_at_rest()


@test
def mdi_moves_to_the_block_and_keeps_history():
    op.tab("mdi")
    op.el("mdi-input").send_keys("G90 G1 X5 Y5 F3000")
    op.el("mdi-send").click()
    wait("X at 5", lambda: op.state() == "IDLE" and op.text("dro-X") == "5.000")
    assert "G90 G1 X5 Y5 F3000" in op.text("mdi-history")


@test
def a_tool_change_shows_its_dialog_and_confirm_goes_on():
    path = os.path.join(tempfile.mkdtemp(), "hmi_tool.nc")
    with open(path, "w") as f:
        f.write("N10 T3 M6\nN20 G1 X1 F3000\nN30 M30\n")
    op.tab("programs")
    op.el("program-upload").send_keys(path)
    wait("uploaded", lambda: op.d.find_element(
        By.CSS_SELECTOR, '[data-testid="program-list"] tr[data-name="hmi_tool.nc"]')).click()
    op.el("program-select").click()
    # (The Run screen names "MDI" until the next start: the list marks the selection.)
    wait("program selected", lambda: "▶" in op.d.find_element(
        By.CSS_SELECTOR, '[data-testid="program-list"] tr[data-name="hmi_tool.nc"]').text)
    op.tab("run")
    op.el("cycle-start").click()
    dialog = op.el("tool-change-dialog")
    wait("tool change dialog", lambda: dialog.is_displayed() and dialog.get_attribute("data-tool") == "3")
    assert "T3" in op.text("tool-change-text"), op.text("tool-change-text")
    op.el("tool-change-confirm").click()
    wait("dialog gone, idle", lambda: not dialog.is_displayed() and op.state() == "IDLE")


@test
def step_jog_moves_x_by_the_step():
    op.tab("jog")
    Select(op.el("jog-step")).select_by_value("1")
    x0 = op.wait_x_at_rest()
    op.el("jog-X-plus").click()
    wait("X one step further", lambda: abs(op.x() - (x0 + 1.0)) < 1e-6 and op.state() == "IDLE")
    op.el("jog-X-minus").click()
    wait("X back", lambda: abs(op.x() - x0) < 1e-6 and op.state() == "IDLE")


@test
def touch_off_on_the_jog_screen_writes_the_entry():
    op.tab("jog")
    x = op.wait_x_at_rest()
    entry = op.el("touch-off-jog-entry")
    entry.clear()
    entry.send_keys("7")
    Select(op.el("touch-off-jog-axis")).select_by_value("X")
    value = op.el("touch-off-jog-value")
    value.clear()
    value.send_keys("2")
    op.el("touch-off-jog-submit").click()
    msg = op.d.find_element(By.CSS_SELECTOR, '.jog-screen [data-testid="message"]')
    wait("touch-off done", lambda: "D7 X" in (msg.get_attribute("textContent") or ""))
    op.tab("offsets")
    row = '[data-testid="offset-table"] tr[data-entry="7"] td'
    cells = wait("entry 7 listed", lambda: op.d.find_elements(By.CSS_SELECTOR, row))
    assert abs(float(cells[2].text) - (x - 2.0)) < 1e-3, (cells[2].text, x)
    op.tab("jog")


# ---- probing (issue #47): the simulated workpiece (a box X 0..100, Y 0..100, Z -60..-10 with a
# 20 mm bore at X50 Y50) and tool setter (at X-40 Y50, top Z-20); probe ball radius 2 mm ----

def jog_step(axis: str, step_mm: float, speed_mm_min: float) -> bytes:
    """JogStepRequest: axis = 1, step_mm = 2, speed_mm_min = 3 (doubles)."""
    return (b"\x0a\x01" + axis.encode() + b"\x11" + struct.pack("<d", step_mm)
            + b"\x19" + struct.pack("<d", speed_mm_min))


def jog_to(*moves) -> None:
    """Moves axes one after the other to machine positions, e.g. ("Z", 0), ("X", -10), by jog
    steps over the API at 3000 mm/min (well inside the suite's 5 mm following window)."""
    for axis, target in moves:
        op.wait_state("IDLE")
        here = float(op.text(f"dro-{axis}"))
        if abs(target - here) > 1e-4:
            grpc_web("JogStep", jog_step(axis, target - here, 3000), TOKEN)
        wait(f"{axis} at {target}", lambda: op.state() == "IDLE" and abs(float(op.text(f"dro-{axis}")) - target) < 1e-3)


def probe(where: str, kind: str, entry: int, axis: str = "", direction: str = "1") -> str:
    """Starts a workflow on the probe panel of `where`; while it runs Start is disabled; returns
    the panel's final state (`done` or `error`)."""
    pid = lambda part: f"probe-{where}-{part}"
    Select(op.el(pid("kind"))).select_by_value(kind)
    op.el(pid("entry")).clear()
    op.el(pid("entry")).send_keys(str(entry))
    if axis:
        Select(op.el(pid("axis"))).select_by_value(axis)
        Select(op.el(pid("dir"))).select_by_value(direction)
    panel = op.el(pid("panel"))
    op.el(pid("start")).click()
    wait("probing", lambda: panel.get_attribute("data-state") == "running")
    assert not op.el(pid("start")).is_enabled(), "Start enabled while probing"
    assert op.text(pid("result")) == "probing …", op.text(pid("result"))
    state = wait("probing ended", lambda: panel.get_attribute("data-state") in ("done", "error")
                 and panel.get_attribute("data-state"))
    assert op.el(pid("start")).is_enabled(), "Start disabled after probing"
    return state


def written(where: str, entry: int, axis: str) -> float:
    """The length the result line says was written for entry and axis."""
    m = re.search(rf"D{entry} {axis}: length (-?[0-9.]+) mm written", op.text(f"probe-{where}-result"))
    assert m, op.text(f"probe-{where}-result")
    return float(m.group(1))


def table_length(entry: int, axis: str) -> float:
    """Entry's length of axis as the Offsets table shows it (columns D, R, X, Y, Z)."""
    col = 2 + "XYZ".index(axis)
    cells = wait(f"entry {entry} listed", lambda: op.d.find_elements(
        By.CSS_SELECTOR, f'[data-testid="offset-table"] tr[data-entry="{entry}"] td'))
    return float(cells[col].text)


@test
def probe_the_tool_setter_writes_the_tool_length():
    op.tab("offsets")
    # The tool's way to the setter is at the axes' rapid speed: from Y10, not Y0 (a 50 mm rapid
    # runs over the suite's 5 mm following window; see docs/hmi.md).
    jog_to(("Z", 0), ("X", 0), ("Y", 10))
    assert probe("offsets", "tool-setter", 21) == "done", op.text("probe-offsets-result")
    length = written("offsets", 21, "Z")
    assert abs(length) < 0.005, length
    assert "found at machine -20.0" in op.text("probe-offsets-result"), op.text("probe-offsets-result")
    # The table refreshed by itself (no tab switch).
    wait("D21 Z in the table", lambda: abs(table_length(21, "Z") - length) < 1e-3)


@test
def probe_an_edge_from_the_jog_screen():
    op.tab("jog")
    jog_to(("Z", 0), ("X", -10), ("Y", 50), ("Z", -20))
    assert probe("jog", "edge", 22, "X", "1") == "done", op.text("probe-jog-result")
    length = written("jog", 22, "X")
    assert abs(length) < 0.005, length
    op.tab("offsets")
    wait("D22 X in the table", lambda: abs(table_length(22, "X") - length) < 1e-3)


@test
def probe_an_edge_that_misses_shows_no_contact():
    op.tab("jog")
    jog_to(("Z", 0), ("X", -10), ("Y", 50), ("Z", -20))
    # Away from the box: 50 mm of search (about 10 s at 300 mm/min) find nothing.
    assert probe("jog", "edge", 23, "X", "-1") == "error"
    text = op.text("probe-jog-result")
    assert "probe_no_contact" in text and text.startswith("Aborted"), text
    assert "err" in op.el("probe-jog-result").get_attribute("class")


@test
def probe_a_bore_writes_its_centre_and_shows_the_diameter():
    op.tab("offsets")
    jog_to(("Z", 0), ("X", 48), ("Y", 51), ("Z", -20))
    try:
        assert probe("offsets", "bore", 24) == "done", op.text("probe-offsets-result")
        x, y = written("offsets", 24, "X"), written("offsets", 24, "Y")
        assert abs(x - 50) < 0.005 and abs(y - 50) < 0.005, (x, y)
        m = re.search(r"bore diameter ([0-9.]+) mm", op.text("probe-offsets-result"))
        assert m and abs(float(m.group(1)) - 20) < 0.01, op.text("probe-offsets-result")
        wait("D24 X and Y in the table", lambda: abs(table_length(24, "X") - x) < 1e-3
             and abs(table_length(24, "Y") - y) < 1e-3)
    finally:
        jog_to(("Z", 0))  # out of the bore for the tests after this one


@test
def probe_labels_and_a_refusal_in_czech():
    cz = Page(browser(lang="cs-CZ"))
    try:
        cz.d.get(URL + "#token=" + TOKEN)
        wait("role operator", lambda: cz.el("role").get_attribute("data-role") == "operator")
        cz.tab("offsets")
        panel = cz.el("probe-offsets-panel")
        kinds = [o.text for o in Select(cz.el("probe-offsets-kind")).options]
        assert kinds == ["snímač nástroje", "hrana", "střed otvoru"], kinds
        assert cz.el("probe-offsets-start").text == "Spustit měření"
        assert "Sonda:" in panel.text and "horní plocha snímače platí" in panel.text, panel.text
        Select(cz.el("probe-offsets-kind")).select_by_value("edge")
        wait("edge labels", lambda: "osa" in panel.text and "směr" in panel.text and "hrana platí" in panel.text)
        Select(cz.el("probe-offsets-kind")).select_by_value("bore")
        wait("bore labels", lambda: "střed X platí" in panel.text and "střed Y platí" in panel.text)
        # A refusal (entry 0: nothing moves) in Czech words, by its code.
        cz.el("probe-offsets-entry").clear()
        cz.el("probe-offsets-entry").send_keys("0")
        cz.el("probe-offsets-start").click()
        wait("refused", lambda: panel.get_attribute("data-state") == "error")
        text = cz.text("probe-offsets-result")
        assert text.startswith("Chybné zadání: [touch_off_invalid] Nastavení korekce odmítnuto"), text
    finally:
        cz.d.quit()


def hold_jog_plus() -> float:
    """Presses X+ in continuous mode and waits until X moved; returns X at the press."""
    op.tab("jog")
    Select(op.el("jog-step")).select_by_value("continuous")
    x0 = op.wait_x_at_rest()
    ActionChains(op.d).move_to_element(op.el("jog-X-plus")).click_and_hold().perform()
    op.wait_state("JOG")
    wait("X moves while held", lambda: op.x() > x0 + 2.0)
    return x0


@test
def continuous_jog_moves_while_pressed_and_stops_on_release():
    hold_jog_plus()
    ActionChains(op.d).release().perform()
    op.wait_x_at_rest()
    assert op.d.execute_script("return cncHmi.jogEnd()") == "pointerup"


@test
def continuous_jog_stops_when_the_page_is_hidden():
    hold_jog_plus()
    main = op.d.current_window_handle
    op.d.switch_to.new_window("tab")
    op.d.switch_to.window(main)
    reason = op.d.execute_script("return cncHmi.jogEnd()")
    ActionChains(op.d).release().perform()
    op.wait_x_at_rest()
    assert reason in ("hidden", "blur"), reason
    for h in op.d.window_handles:
        if h != main:
            op.d.switch_to.window(h)
            op.d.close()
    op.d.switch_to.window(main)


@test
def continuous_jog_stops_when_the_connection_is_cut():
    hold_jog_plus()
    PROXY.cut()
    wait("connection lost shown", lambda: op.text("connection-state") == "CONNECTION LOST")
    assert "stale" in op.d.find_element(By.CSS_SELECTOR, "aside.dro").get_attribute("class")
    x_cut = op.x()
    # cncd's lease lapses: the axis brakes to rest while the browser cannot reach it.
    time.sleep(1.5)  # not an assertion on time: the page is cut off, this is the outage
    PROXY.restore()
    ActionChains(op.d).release().perform()
    op.wait_live()
    x_rest = op.wait_x_at_rest()
    # Without the lease the jog would still run (no soft limits here): it stopped close by.
    assert x_rest - x_cut < 30.0, f"X ran on {x_rest - x_cut:.1f} mm after the cut"


@test
def an_alarm_shows_in_the_alarm_list_and_reset_clears_it():
    # A 5 mm following window: a rapid move (200 mm/s, following error v/kv = 6.7 mm) faults.
    op.tab("mdi")
    op.el("mdi-input").send_keys("G90 G0 X300")
    op.el("mdi-send").click()
    op.wait_state("FAULT")
    op.tab("alarms")
    wait("an active alarm listed", lambda: op.d.find_elements(
        By.CSS_SELECTOR, '[data-testid="alarm-list"] .alarm.active'))
    op.tab("run")
    op.el("reset").click()
    op.wait_state("IDLE")
    op.tab("alarms")
    wait("alarm list empty", lambda: not op.d.find_elements(
        By.CSS_SELECTOR, '[data-testid="alarm-list"] .alarm'))
    wait("history shows the clear", lambda: op.d.find_elements(
        By.CSS_SELECTOR, '[data-testid="alarm-history"] .alarm.cleared'))


@test
def kiosk_token_in_the_fragment_signs_in_and_leaves_the_address_bar():
    obs.d.get(URL + "#token=" + TOKEN)
    obs.wait_live()
    wait("role operator", lambda: obs.text("role") == "operator")
    assert TOKEN not in obs.d.current_url



def grpc_web(method: str, message: bytes, token: str) -> None:
    """One unary call of `cnc.v1.Machine` over grpc-web to cncd's HMI origin (not through the
    cuttable proxy), as any client makes it; raises unless the grpc-status is OK."""
    req = urllib.request.Request(
        f"http://{target.hostname}:{target.port}/cnc.v1.Machine/{method}",
        data=b"\x00" + len(message).to_bytes(4, "big") + message, method="POST",
        headers={"content-type": "application/grpc-web+proto", "x-grpc-web": "1",
                 "authorization": f"Bearer {token}"})
    with urllib.request.urlopen(req, timeout=10) as r:
        status, text = r.headers.get("grpc-status"), r.headers.get("grpc-message", "")
        body = r.read()
    # Not trailers-only: the status is in the trailer frame (flag 0x80) at the end.
    i = 0
    while status is None and i + 5 <= len(body):
        n = int.from_bytes(body[i + 1:i + 5], "big")
        if body[i] & 0x80:
            fields = dict(line.split(":", 1) for line in body[i + 5:i + 5 + n].decode().split("\r\n") if ":" in line)
            status, text = fields.get("grpc-status"), fields.get("grpc-message", "")
        i += 5 + n
    assert status == "0", f"{method}: grpc-status {status} {text}"


def name_value(name: str, value) -> bytes:
    """SimSetInputRequest / ForceOutputRequest: name = 1, optional bool value = 2 (absent:
    release)."""
    b = name.encode()
    return b"\x0a" + bytes([len(b)]) + b + (b"" if value is None else b"\x10" + bytes([int(value)]))


SIM_INPUTS = ("estop", "x_limit_neg", "x_limit_pos", "y_limit_neg", "y_limit_pos", "z_limit_neg",
              "z_limit_pos", "door")


@test
def the_io_screen_lists_the_simulated_inputs_and_outputs():
    op.tab("io")
    for name in SIM_INPUTS:
        wait(f"input {name} listed", lambda: op.el(f"io-in-{name}"))
    for name in ("coolant", "spindle_enable"):
        wait(f"output {name} listed", lambda: op.el(f"io-out-{name}"))
    estop = op.el("io-in-estop")
    wait("the e-stop chain reads 1 (closed)", lambda: estop.get_attribute("data-value") == "1")
    assert "estop" in estop.text and "sim" in estop.text, estop.text
    assert "M8" in op.el("io-out-coolant").text
    # Forcing is an admin's: an operator does not even see the buttons.
    assert not op.el("io-force-coolant-on").is_displayed()
    assert not op.el("io-sim-estop-0").is_displayed()


@test
def an_open_estop_chain_shows_the_banner_and_faults_the_machine():
    op.wait_state("IDLE")
    grpc_web("SimSetInput", name_value("estop", False), ADMIN_TOKEN)
    wait("e-stop banner", lambda: "E-STOP OPEN" in op.text("io-banner"))
    wait("estop lamp off", lambda: op.el("io-in-estop").get_attribute("data-value") == "0")
    op.wait_state("FAULT")
    op.tab("run")
    wait("e-stop on the Run screen", lambda: op.d.find_element(
        By.CSS_SELECTOR, '[data-testid="run-io"] [data-kind="estop"]').is_displayed())
    grpc_web("SimSetInput", name_value("estop", None), ADMIN_TOKEN)
    wait("the strip gone once the chain closes", lambda: not op.el("run-io").is_displayed())
    op.el("reset").click()
    op.wait_state("IDLE")


@test
def an_admin_forces_coolant_after_a_confirmation():
    adm = obs
    adm.d.get(URL + "#token=" + ADMIN_TOKEN)
    adm.wait_live()
    wait("role admin", lambda: adm.text("role") == "admin")
    adm.tab("io")
    on = wait("force button", lambda: adm.el("io-force-coolant-on").is_displayed() and adm.el("io-force-coolant-on"))
    row = adm.el("io-out-coolant")
    assert row.get_attribute("data-value") == "0" and row.get_attribute("data-forced") == "0"
    # Cancel first: nothing is forced.
    on.click()
    wait("confirmation", lambda: adm.el("io-confirm").is_displayed())
    adm.el("io-confirm-no").click()
    wait("confirmation closed", lambda: not adm.el("io-confirm").is_displayed())
    time.sleep(0.3)  # not an assertion on time: a forcing would show within this
    assert row.get_attribute("data-forced") == "0"
    on.click()
    q = wait("confirmation", lambda: adm.el("io-confirm").is_displayed() and adm.text("io-confirm-text"))
    assert "coolant" in q and "1 (on)" in q, q
    adm.el("io-confirm-yes").click()
    wait("coolant FORCED at 1", lambda: row.get_attribute("data-forced") == "1"
         and row.get_attribute("data-value") == "1" and "FORCED" in row.text)
    adm.tab("run")
    wait("forced on the Run screen", lambda: "coolant=1" in adm.text("run-io"))
    # The operator's page sees it too, live.
    wait("forced seen by the operator", lambda: "coolant=1" in op.text("run-io"))
    adm.tab("io")
    adm.el("io-force-coolant-release").click()
    wait("release confirmation", lambda: "Release output coolant" in adm.text("io-confirm-text"))
    adm.el("io-confirm-yes").click()
    wait("coolant released", lambda: row.get_attribute("data-forced") == "0" and row.get_attribute("data-value") == "0")


@test
def the_constants_screen_names_each_constant_with_its_unit():
    op.tab("constants")
    row = wait("R384 listed", lambda: op.d.find_element(
        By.CSS_SELECTOR, '[data-testid="constants-table"] tr[data-number="384"]'))
    assert "contour accuracy" in row.find_element(By.CSS_SELECTOR, ".c-name").text
    assert "µm" in row.find_element(By.CSS_SELECTOR, ".c-unit").text
    assert "SPEC §7.2" in row.find_element(By.CSS_SELECTOR, ".c-meaning").text
    r52 = op.d.find_element(By.CSS_SELECTOR, '[data-testid="constants-table"] tr[data-number="52"]')
    assert r52.find_element(By.CSS_SELECTOR, ".c-unit").text == "mm/s²"


@test
def io_constants_and_run_fit_800_by_480():
    # The admin's page of the test above, its viewport set to the panel (no second browser).
    small = obs
    viewport(small.d, 800, 480)
    try:
        wait("role admin", lambda: small.text("role") == "admin")
        grpc_web("SimSetInput", name_value("door", False), ADMIN_TOKEN)
        for screen in ("io", "constants", "run"):
            small.tab(screen)
            if screen == "io":
                wait("door banner", lambda: "DOOR OPEN" in small.text("io-banner"))
            if screen == "constants":
                wait("constants listed", lambda: small.d.find_elements(
                    By.CSS_SELECTOR, '[data-testid="constants-table"] tr[data-number="384"]'))
            if screen == "run":
                wait("door on the Run screen", lambda: "DOOR OPEN" in small.text("run-io"))
            # Neither the page nor the screen's area nor its lists scroll sideways (the
            # program listing may: its lines are the program's).
            wide = small.d.execute_script("""
                const els = [document.documentElement, document.querySelector('.view'),
                  ...document.querySelectorAll('.screen:not([hidden]) .scroll')];
                return els.filter((e) => e.scrollWidth > e.clientWidth + 1)
                  .map((e) => `${e.className || e.tagName} ${e.scrollWidth} > ${e.clientWidth}`);""")
            assert not wide, f"{screen} scrolls sideways: {wide}"
            small.shot(f"hmi_{screen}_800x480.png", os.environ.get("CNC_FAIL_SHOTS", ""))
    finally:
        grpc_web("SimSetInput", name_value("door", None), ADMIN_TOKEN)
        viewport(small.d, 1280, 800)


# ---- panels and language (issue #51) ---------------------------------------------------------

# The panels machines have: 7" 800 x 480, 10" 1024 x 600, 1280 x 800, a tablet standing up.
PANELS = ((800, 480), (1024, 600), (1280, 800), (800, 1280))

# From the elements' boxes: the controls an operator must always reach are inside the viewport,
# at least 48 px (about 9 mm) each way, and none overlaps another; no tab label is cut; the
# page itself does not scroll.
LAYOUT_JS = """
const vw = innerWidth, vh = innerHeight, out = [];
const tid = (id) => document.querySelector(`[data-testid="${id}"]`);
const box = (el) => el.getBoundingClientRect();
const inside = (n, r) => {
  if (r.width === 0 || r.height === 0) out.push(`${n} not shown`);
  else if (r.left < -0.5 || r.top < -0.5 || r.right > vw + 0.5 || r.bottom > vh + 0.5)
    out.push(`${n} outside ${vw}x${vh}: ${r.left|0},${r.top|0} ${r.width|0}x${r.height|0}`);
};
const touch = (n, r) => { if (r.width < 48 || r.height < 48) out.push(`${n} ${r.width|0}x${r.height|0} under 48 px`); };
const controls = ['cycle-start', 'feed-hold', 'resume', 'reset', 'stop'].map((id) => [id, tid(id)]);
// The header's other buttons, as far as the role shows them (Sign in or Sign out).
for (const id of ['login-submit', 'logout', 'lang-switch']) if (tid(id)?.getClientRects().length) controls.push([id, tid(id)]);
const tabs = [...document.querySelectorAll('nav .tab')].map((t) => [t.dataset.testid, t]);
const dro = [...document.querySelectorAll('aside.dro [data-testid^="dro-"]')].map((e) => [e.dataset.testid, e]);
if (!dro.length) out.push('no DRO axis shown');
const all = [...controls, ...tabs, ...dro, ['dro', document.querySelector('aside.dro')]];
for (const [n, el] of all) if (!el) out.push(`${n} missing`); else inside(n, box(el));
for (const [n, el] of [...controls, ...tabs]) {
  if (!el) continue;
  touch(n, box(el));
  // A label cut (tabs: one line, clipped) or spilling out of its button.
  if (el.scrollWidth > el.clientWidth + 0.5 || el.scrollHeight > el.clientHeight + 0.5)
    out.push(`${n} label cut: ${el.scrollWidth}x${el.scrollHeight} in ${el.clientWidth}x${el.clientHeight}`);
}
for (const [n, el] of dro) if (el.scrollWidth > el.clientWidth + 0.5) out.push(`${n} cut`);
const solid = [...controls, ...tabs, ...dro].filter(([, el]) => el);
for (let i = 0; i < solid.length; i++) for (let j = i + 1; j < solid.length; j++) {
  const a = box(solid[i][1]), b = box(solid[j][1]);
  const w = Math.min(a.right, b.right) - Math.max(a.left, b.left), h = Math.min(a.bottom, b.bottom) - Math.max(a.top, b.top);
  if (w > 0.5 && h > 0.5) out.push(`${solid[i][0]} overlaps ${solid[j][0]}`);
}
const shown = [...document.querySelectorAll('.screen')].filter((e) => e.getClientRects().length);
if (shown.length !== 1) out.push(`${shown.length} screens shown`);
const de = document.documentElement;
if (de.scrollWidth > vw || de.scrollHeight > vh) out.push(`the page scrolls: ${de.scrollWidth}x${de.scrollHeight}`);
return out;
"""


def layout_problems(page: Page) -> list:
    return page.d.execute_script(LAYOUT_JS)


def check_panels(page: Page, shots: str = "", sizes=PANELS) -> None:
    """Run and Jog at every panel size: the layout holds (LAYOUT_JS); a Run screenshot each."""
    problems = []
    try:
        for w, h in sizes:
            viewport(page.d, w, h)
            for screen in ("jog", "run"):
                page.tab(screen)
                # Laid out again at the new size (two frames), then measured.
                page.d.execute_script("return new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)))")
                problems += [f"{w}x{h} {screen}: {p}" for p in layout_problems(page)]
            if shots:
                page.shot(f"hmi_run_{w}x{h}.png", shots)
    finally:
        viewport(page.d, 1280, 800)
    assert not problems, "\n".join(problems)


@test
def run_and_jog_hold_at_every_panel_size_in_english():
    # The admin's page (signed in: the header shows Sign out); a full-HD screen too.
    if not obs.d.current_url.startswith(URL):  # run alone (CNC_TESTS)
        obs.d.get(URL + "#token=" + ADMIN_TOKEN)
    obs.wait_live()
    check_panels(obs, sizes=PANELS + ((1920, 1080),))


def catalogue_vocabulary(page: Page) -> set:
    """Words of the English catalogue that are not Czech: seen on a Czech screen, they are
    English left over. Codes, numbers, units and names (in both catalogues) drop out."""
    cats = page.d.execute_script("return cncHmi.catalogues")
    words = lambda s: {w.lower() for w in re.findall(r"[A-Za-z]{3,}", s)}
    english = set().union(*(words(v) for k, v in cats["en"].items() if cats["cs"][k] != v))
    czech = set().union(*(words(v) for v in cats["cs"].values()))
    return english - czech


# Every visible text of the page (selects: the chosen option) but what is data, not labels:
# elements marked translate="no" (program text and names, I/O names, MDI blocks).
VISIBLE_TEXT_JS = """
const out = [];
const walk = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
for (let n = walk.nextNode(); n; n = walk.nextNode()) {
  const el = n.parentElement, s = n.textContent.trim();
  if (!s || !el || el.closest('[translate=no], option, script, style')) continue;
  if (!el.getClientRects().length || getComputedStyle(el).visibility === 'hidden') continue;
  out.push(s);
}
for (const sel of document.querySelectorAll('select')) if (sel.getClientRects().length) out.push(sel.selectedOptions[0]?.text ?? '');
return out;
"""


# Words the Czech manuals use as they are (strojní konstanta R234: "limit pro test spojitosti").
SHARED_WORDS = {"limit"}


def english_left(page: Page, vocabulary: set) -> list:
    left = []
    for text in page.d.execute_script(VISIBLE_TEXT_JS):
        for token in text.split():
            # Identifiers, codes and numbers (hmi_test.nc, [unknown_address], 0x1A, N30) are not words.
            if re.search(r"[_0-9@#/\\.]", token) or token.startswith("["):
                continue
            w = token.strip("()[]{}:;,.!?…—-–\"'«»").lower()
            # Czech words (with their own letters) never match: only plain Latin words can.
            if re.fullmatch(r"[a-z]+", w) and w in vocabulary and w not in SHARED_WORDS:
                left.append(f"{w!r} in {text!r}")
    return left


@test
def a_czech_browser_gets_a_czech_screen_that_holds_at_every_panel_size():
    cz = Page(browser(lang="cs-CZ"))
    try:
        cz.d.get(URL)
        cz.wait_live()
        assert cz.d.execute_script("return document.documentElement.lang") == "cs"
        # Observer (no token): the header holds the token field and Sign in, its widest form.
        check_panels(cz, SHOTS)
        vocabulary = catalogue_vocabulary(cz)
        assert {"feed", "hold", "spindle"} <= vocabulary, sorted(vocabulary)[:20]
        # The check bites: the English page of the same machine is full of such words.
        assert len(english_left(obs, vocabulary)) > 20, english_left(obs, vocabulary)
        left = []
        for screen in ("run", "preview", "programs", "mdi", "jog", "homing", "offsets", "constants",
                       "plc", "io", "alarms"):
            cz.tab(screen)
            if screen == "constants":
                wait("constants listed", lambda: cz.d.find_elements(
                    By.CSS_SELECTOR, '[data-testid="constants-table"] tr[data-number="384"]'))
                name = cz.d.find_element(By.CSS_SELECTOR, 'tr[data-number="236"] .c-name').text
                assert name == "zrychlení pro plynulou návaznost", name
            if screen == "programs":
                # The header row comes with the rows (one fill): the list is there.
                wait("programs listed", lambda: cz.d.find_elements(By.CSS_SELECTOR, '[data-testid="program-list"] tr'))
            if screen == "preview" and cz.text("program-name") != "—":
                wait("preview drawn", lambda: cz.el("preview").get_attribute("data-state") == "drawn")
            if screen == "io":
                wait("inputs listed", lambda: cz.el("io-in-estop"))
            if screen == "alarms":
                # After the suite's alarm tests there is a history to read (alone, none comes).
                if not ONLY:
                    wait("alarm history", lambda: cz.d.find_elements(By.CSS_SELECTOR, '[data-testid="alarm-history"] .alarm'))
            left += [f"{screen}: {x}" for x in english_left(cz, vocabulary)]
            if screen in ("preview", "constants", "alarms"):
                cz.shot(f"hmi_{screen}_cs.png", os.environ.get("CNC_FAIL_SHOTS", ""))
        # A refusal with a diagnostic code reads in Czech too (a program that does not check).
        path = os.path.join(tempfile.mkdtemp(), "hmi_cs_bad.nc")
        with open(path, "w") as f:
            f.write("N10 G1 X10 F500\nN30 G1 X0 Y0 Q7\n")
        cz.d.get(URL + "#token=" + TOKEN)
        wait("role operator", lambda: cz.el("role").get_attribute("data-role") == "operator")
        cz.tab("programs")
        cz.el("program-upload").send_keys(path)
        link = wait("a diagnostic", lambda: cz.d.find_element(By.CSS_SELECTOR, '[data-testid="diagnostics"] a[data-line="2"]'))
        assert "[unknown_address] řádek 2:" in link.text and "Adresa, kterou jazyk nemá." in link.text, link.text
        left += [f"programs: {x}" for x in english_left(cz, vocabulary)]
        cz.shot("hmi_programs_cs.png", os.environ.get("CNC_FAIL_SHOTS", ""))
        assert not left, "English left on the Czech screen:\n" + "\n".join(left)
        # The switch on the screen: English, then Czech again (remembered across loads).
        cz.el("lang-switch").click()
        wait("English", lambda: cz.d.execute_script("return document.documentElement.lang") == "en"
             and cz.el("tab-run").text == "Run")
        cz.d.refresh()
        wait("still English", lambda: cz.d.execute_script("return document.documentElement.lang") == "en")
        cz.el("lang-switch").click()
        wait("Czech again", lambda: cz.d.execute_script("return document.documentElement.lang") == "cs"
             and cz.el("tab-run").text == "Automat")
    finally:
        cz.d.quit()


passed = failed = 0
for fn in results:
    if ONLY and not any(x in fn.__name__ for x in ONLY):
        continue
    t0 = time.monotonic()
    try:
        fn()
        passed += 1
        print(f"ok   {fn.__name__} ({time.monotonic() - t0:.1f} s)", flush=True)
    except Exception:
        failed += 1
        print(f"FAIL {fn.__name__}", flush=True)
        traceback.print_exc()
        op.shot(f"fail_{fn.__name__}.png", os.environ.get("CNC_FAIL_SHOTS", ""))
for d in (op.d, obs.d):
    d.quit()
print(f"{passed} passed, {failed} failed")
sys.exit(1 if failed else 0)
