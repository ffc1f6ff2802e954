"""Headless Chromium for the browser suite and benchmark: Debian's chromium and chromedriver
(`--no-sandbox`: the suites run as root), a 1280 x 800 viewport, in English unless `lang`
says otherwise (the browser's language is what the page starts in: `navigator.language`)."""

import os

from selenium import webdriver
from selenium.webdriver.chrome.service import Service


def browser(width: int = 1280, height: int = 800, lang: str = "en-US") -> webdriver.Chrome:
    o = webdriver.ChromeOptions()
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              f"--window-size={width},{height + 100}", "--force-device-scale-factor=1",
              "--enable-precise-memory-info", f"--lang={lang}"):
        o.add_argument(a)
    o.add_experimental_option("prefs", {"intl.accept_languages": lang})
    o.binary_location = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    o.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    d = webdriver.Chrome(service=Service(os.environ.get("CHROMEDRIVER", "/usr/bin/chromedriver")),
                         options=o)
    viewport(d, width, height)
    return d


def viewport(d: webdriver.Chrome, width: int, height: int) -> None:
    """Sets the page's viewport (the panel's size), as a panel's browser would have it."""
    d.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                      {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})
