"""Headless Chromium for the browser suite and benchmark: Debian's chromium and chromedriver
(`--no-sandbox`: the suites run as root), a 1280 x 800 viewport."""

import os

from selenium import webdriver
from selenium.webdriver.chrome.service import Service


def browser(width: int = 1280, height: int = 800) -> webdriver.Chrome:
    o = webdriver.ChromeOptions()
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              f"--window-size={width},{height + 100}", "--force-device-scale-factor=1",
              "--enable-precise-memory-info"):
        o.add_argument(a)
    o.binary_location = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    o.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    d = webdriver.Chrome(service=Service(os.environ.get("CHROMEDRIVER", "/usr/bin/chromedriver")),
                         options=o)
    d.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                      {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})
    return d
