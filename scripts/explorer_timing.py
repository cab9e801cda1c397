"""Time cradle explore in chromium (Playwright): first paint, click to a drawn trace and a
wheel-zoom repaint, three page loads. python3 scripts/explorer_timing.py CRADLE_BIN TABLE
[--chain CHAIN_TABLE] (the table: python3 scripts/grid.py 1000 1000 > g.toml; cradle sweep
g.toml --out g.csv --model hard-sphere --backend cpu). With --chain, a table of a sweep of
long chains (examples/chain_explore.toml): the click on its middle cell to a drawn
space-time image, three times."""
import subprocess, sys, time, urllib.request, socket
from playwright.sync_api import sync_playwright
BIN = sys.argv[1]
ARGS = ["--headless", "--no-sandbox", "--disable-gpu"]


def serve(table):
    s = socket.socket(); s.bind(("127.0.0.1", 0)); port = s.getsockname()[1]; s.close()
    p = subprocess.Popen([BIN, "explore", table, "--port", str(port)], stderr=subprocess.PIPE, text=True)
    url = f"http://127.0.0.1:{port}/"
    for _ in range(600):
        try:
            urllib.request.urlopen(url + "api/meta", timeout=1); break
        except Exception:
            time.sleep(0.1)
    return p, url


if "--chain" in sys.argv:
    p, url = serve(sys.argv[sys.argv.index("--chain") + 1])
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path="/usr/bin/chromium", args=ARGS)
        for k in range(3):
            page = b.new_page(viewport={"width": 1400, "height": 900})
            page.goto(url); page.wait_for_selector("body[data-ready='1']", timeout=60000)
            box = page.get_by_test_id("phase-map").bounding_box()
            t1 = time.time(); page.mouse.click(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
            page.get_by_test_id("spacetime-image").wait_for(timeout=30000); click = time.time() - t1
            beads = page.evaluate("document.querySelector('#run .note').textContent")
            print(f"chain load {k}: click to space-time image {click:.2f} s ({beads})")
            page.close()
        b.close()
    p.terminate()
    sys.exit(0)

p, url = serve(sys.argv[2])
with sync_playwright() as pw:
    b = pw.chromium.launch(executable_path="/usr/bin/chromium", args=ARGS)
    for k in range(3):
        page = b.new_page(viewport={"width": 1400, "height": 900})
        t0 = time.time(); page.goto(url); page.wait_for_selector("body[data-ready='1']", timeout=60000)
        paint = time.time() - t0
        cv = page.get_by_test_id("phase-map"); box = cv.bounding_box()
        t1 = time.time(); page.mouse.click(box["x"] + 0.7 * box["width"], box["y"] + 0.3 * box["height"])
        page.get_by_test_id("trace-plot").wait_for(timeout=20000); click = time.time() - t1
        cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        before = cv.get_attribute("data-x-range")
        page.mouse.move(cx, cy); t2 = time.time(); page.mouse.wheel(0, -400)
        page.wait_for_function(f"document.querySelector('[data-testid=phase-map]').dataset.xRange !== {before!r}")
        zoom = time.time() - t2
        print(f"load {k}: first paint {paint:.2f} s, click to trace {click:.2f} s, wheel zoom repaint {zoom:.3f} s, x ticks {page.get_by_test_id('x-axis').locator('.tick').all_inner_texts()}")
        page.close()
    b.close()
p.terminate()
