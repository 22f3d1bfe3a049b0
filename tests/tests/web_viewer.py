"""Drives the web viewer in headless Chromium (Debian's, through Playwright; no browser
download): argv = viewer URL, token, session label, screenshot path. Prints one JSON object:
what the page showed (see tests/tests/it/web.rs)."""
import json
import sys
import time

from playwright.sync_api import sync_playwright

url, token, label, shot = sys.argv[1:5]
# the flags a closed network needs (no background connections, no component updates)
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]

# pixels of the canvas that are not background, left of the scale bar and its labels (130 px)
# and not of the tool's colour (or of its edges over the background); "red": those drawn as damaged tissue or cut walls
MEASURE = """() => {
  const c = document.getElementById('canvas');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  const right = c.width - 130 * (window.devicePixelRatio || 1);
  let n = 0, red = 0, x0 = 1e9, y0 = 1e9, x1 = -1, y1 = -1;
  for (let y = 0; y < c.height; y++) for (let x = 0; x < right; x++) {
    const i = 4 * (y * c.width + x);
    const [r, g, b] = [d[i], d[i + 1], d[i + 2]];
    const bg = Math.abs(r - 0x12) + Math.abs(g - 0x16) + Math.abs(b - 0x1c) < 12;
    // the tool's white, and its edges blended with the background in any proportion (the
    // faintest pixels of the force's thin line are 3.6 % white: a threshold on the blend
    // counted them as organ, far above it)
    const o = [0xf4 - 0x12, 0xf4 - 0x16, 0xf4 - 0x1c], q = [r - 0x12, g - 0x16, b - 0x1c];
    const t = (q[0] * o[0] + q[1] * o[1] + q[2] * o[2]) / (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
    const tool = t > 0 && Math.hypot(q[0] - t * o[0], q[1] - t * o[1], q[2] - t * o[2]) < 24;
    if (bg || tool) continue;
    if (r > 60 && r > 1.4 * g && r > 1.4 * b) red++;
    n++; x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y);
  }
  return {area: n, red, bbox: [x0, y0, x1, y1], width: c.width, height: c.height};
}"""

out = {}
with sync_playwright() as p:
    browser = p.chromium.launch(executable_path="/usr/bin/chromium", headless=True, args=ARGS)
    page = browser.new_page(viewport={"width": 1200, "height": 800}, device_scale_factor=1)
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(url)
    # the server has tokens: the page asks for one
    page.wait_for_selector("#login.shown", timeout=20000)
    page.fill("#token", token)
    page.click("#token-ok")
    item = page.locator("#sessions li", has_text=label)
    item.wait_for(timeout=20000)
    out["listed"] = item.inner_text()
    item.click()
    page.wait_for_function("Number(document.getElementById('frames').textContent) > 10", timeout=30000)
    # frames counted over 3 s of the page's own clock
    f0, t0 = int(page.inner_text("#frames")), time.monotonic()
    time.sleep(3)
    f1, t1 = int(page.inner_text("#frames")), time.monotonic()
    out["frame_rate_hz"] = (f1 - f0) / (t1 - t0)
    # the force readout while the probe presses (the largest seen over 5 s)
    force = 0.0
    until = time.monotonic() + 5
    while time.monotonic() < until and force == 0.0:
        force = max(force, float(page.inner_text("#force").split()[0]))
        time.sleep(0.05)
    out["force_n"] = force
    # every tool's force by name, in a session that moves named tools ("–" otherwise)
    out["tools"] = page.inner_text("#tools")
    # the organ drawn at rest would be the same shape: pause and measure the picture shown
    page.click("#pause")
    time.sleep(0.2)
    out["canvas"] = page.evaluate(MEASURE)
    page.locator("#canvas").screenshot(path=shot)
    page.screenshot(path=shot.replace(".png", "-page.png"))
    out["errors"] = errors
    browser.close()
print(json.dumps(out))
