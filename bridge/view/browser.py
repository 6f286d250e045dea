"""Headless chromium through selenium, from Debian's packages only.

`make chromium` (and so `make test`) installs chromium and chromium-driver with
apt-get; selenium is
pointed at both explicitly, and SE_OFFLINE keeps Selenium Manager from ever
downloading a browser or a driver.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from bridge.errors import UsageError

CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")


class BrowserMissing(UsageError):
    """No headless browser here (names what is missing and how to get it)."""


def headless(width: int = 1200, height: int = 900) -> Any:
    """A headless chromium WebDriver; the caller quits it."""
    missing = [str(p) for p in (CHROMIUM, CHROMEDRIVER) if not p.exists()]
    if missing:
        raise BrowserMissing(f"{' and '.join(missing)} missing: `make chromium` installs Debian's "
                             "chromium and chromium-driver (as root; else sudo apt-get "
                             "install chromium chromium-driver)")
    os.environ["SE_OFFLINE"] = "true"
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        raise BrowserMissing("selenium is not installed: `make venv` installs the dev "
                             "extras") from None
    opts = webdriver.ChromeOptions()
    opts.binary_location = str(CHROMIUM)
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                f"--window-size={width},{height}"):
        opts.add_argument(arg)
    return webdriver.Chrome(service=Service(executable_path=str(CHROMEDRIVER)), options=opts)


def screenshot(url: str, out: Path, tick: int, timeout: float = 60.0) -> None:
    """Load the view at `url`, wait until the page shows `tick`, save a PNG."""
    from selenium.webdriver.support.ui import WebDriverWait
    driver = headless(1500, 1100)      # the arena, the plots and the side panel side by side
    try:
        driver.get(url)
        WebDriverWait(driver, timeout).until(
            lambda d: d.execute_script("return document.body.dataset.tick") == str(tick))
        driver.save_screenshot(str(out))
    finally:
        driver.quit()
