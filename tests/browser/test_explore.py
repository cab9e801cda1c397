"""`cradle explore` end to end in a real browser: Debian's chromium driven by
Playwright for Python (executable_path: no browser download).

    pip install -r python/requirements-test.txt playwright
    CRADLE_BIN=target/debug/cradle pytest tests/browser

Needs /usr/bin/chromium (apt-get install chromium). Writes the page's
screenshot to results/explorer.png (EXPLORER_SCREENSHOT overrides)."""

import contextlib
import csv
import io
import json
import os
import re
import shutil
import socket
import subprocess
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def cradle_bin():
    env = os.environ.get("CRADLE_BIN")
    if env:
        return str(Path(env).resolve())
    for p in ("target/release/cradle", "target/debug/cradle"):
        if (ROOT / p).exists():
            return str(ROOT / p)
    pytest.skip("no cradle binary: build it (cargo build) or set CRADLE_BIN")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def explorer(d, name, spec_text):
    """Sweep `spec_text` into d/NAME.csv on the CPU, serve it with `cradle
    explore` (run in d) on a free port, wait until it answers; yields the
    page's URL and the table, and stops the server after."""
    spec = d / f"{name}.toml"
    spec.write_text(spec_text)
    table = d / f"{name}.csv"
    subprocess.run([cradle_bin(), "sweep", spec, "--out", table, "--backend", "cpu"], check=True,
                   capture_output=True, cwd=d)
    with serving(d, table) as url:
        yield url, table


@contextlib.contextmanager
def serving(d, table):
    """`cradle explore TABLE` (run in d) on a free port, once it answers;
    yields the page's URL and stops the server after."""
    port = free_port()
    p = subprocess.Popen([cradle_bin(), "explore", table.name, "--port", str(port)], cwd=d,
                         stderr=subprocess.PIPE, text=True)
    url = f"http://127.0.0.1:{port}/"
    try:
        for _ in range(200):
            try:
                urllib.request.urlopen(url + "api/meta", timeout=1)
                break
            except (urllib.error.URLError, ConnectionError):
                time.sleep(0.05)
        yield url
    finally:
        p.terminate()
        p.wait(timeout=10)


@contextlib.contextmanager
def opened(url):
    """The page at `url` in chromium, once it says it is ready; yields the
    page and the list of page errors seen (checked empty by the caller)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        errors = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(url)
        page.wait_for_selector("body[data-ready='1']", timeout=20_000)
        try:
            yield page, errors
        finally:
            browser.close()


# The pixels under a plot's testid element (a canvas, or a uPlot chart's
# plot area: the part of its canvas below it).
PIXELS = """(id) => { const el = document.querySelector(`[data-testid=${id}]`);
    const c = el.tagName === 'CANVAS' ? el : el.closest('.uplot').querySelector('canvas');
    const r = el.getBoundingClientRect(), cr = c.getBoundingClientRect(), k = c.width / cr.width;
    return c.getContext('2d').getImageData(Math.round((r.left - cr.left) * k), Math.round((r.top - cr.top) * k),
                                           Math.round(r.width * k), Math.round(r.height * k)).data; }"""


def distinct_colours(page, testid, every):
    """How many colours a plot's area holds, looking at every `every`-th pixel."""
    return page.evaluate(
        f"""([id, every]) => {{ const d = ({PIXELS})(id);
                   const s = new Set(); for (let i = 0; i < d.length; i += 4 * every) s.add(d[i] + ',' + d[i+1] + ',' + d[i+2]);
                   return s.size; }}""",
        [testid, every],
    )


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    if not Path(CHROMIUM).exists():
        pytest.skip(f"no browser at {CHROMIUM}: apt-get install chromium")
    with explorer(tmp_path_factory.mktemp("explore"), "map",
                  "[scene]\nballs = 5\nvelocity = [1.0, 0, 0, 0, 0]\n"
                  "[[axis]]\nparam = \"mass[2]\"\nlogspace = [0.0064, 0.64, 60]\n"
                  "[[axis]]\nparam = \"gap\"\nlinspace = [0.0, 2e-5, 40]\n") as served:
        yield served


def sig_digits(text):
    """Significant digits of a number as printed (0 for anything else)."""
    m = re.fullmatch(r"-?(\d*)\.?(\d*)(?:e[-+]?\d+)?", text.strip(), re.I)
    if not m or not (m.group(1) + m.group(2)):
        return 0
    return len((m.group(1) + m.group(2)).lstrip("0"))


def get(url):
    try:
        with urllib.request.urlopen(url, timeout=30) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def test_bad_requests_get_json_errors_and_the_server_keeps_serving(server):
    url, _ = server
    for path, code, needle in [
        ("api/scene?id=abc", 400, "not a whole number"),
        ("api/scene?id=-1", 400, "not a whole number"),
        ("api/scene?id=999999", 404, "no scene 999999"),
        ("api/scene", 400, "`id` is required"),
        ("api/row?id=1e3", 400, "not a whole number"),
        ("api/map?x=gap&y=nope&z=ejected", 400, "not an axis"),
        ("api/map?x=gap&y=mass[2]&z=ejected&at=0", 400, "one per axis"),
        ("../../etc/passwd", 404, "no such page"),
        ("api/../../Cargo.toml", 404, "no such page"),
    ]:
        status, body = get(url + path)
        assert status == code and needle in body["error"], (path, status, body)
    status, body = get(url + "api/row?id=3")
    assert status == 200 and body["row"][0] == ["id", "3"]
    # The plotting library comes from the binary, and the table's units with the axes.
    with urllib.request.urlopen(url + "vendor/uPlot.js", timeout=30) as r:
        assert r.status == 200 and "javascript" in r.headers["Content-Type"] and b"uPlot" in r.read(200)
    status, body = get(url + "api/meta")
    units = {a["name"]: a["unit"] for a in body["axes"]}
    assert units == {"mass[2]": "kg", "gap": "m"}, units


def test_the_page_draws_the_map_and_a_click_opens_that_scene(server):
    from playwright.sync_api import sync_playwright

    url, table = server
    rows = table.read_text().splitlines()
    header = rows[0].split(",")
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        errors = []
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: errors.append(str(e)))
        t0 = time.time()
        page.goto(url)
        page.wait_for_selector("body[data-ready='1']", timeout=20_000)
        first_paint = time.time() - t0
        cv = page.get_by_test_id("phase-map")
        # x: the first axis (mass[2], 60 values), y: the second (gap, 40).
        assert cv.get_attribute("data-nx") == "60" and cv.get_attribute("data-ny") == "40"
        # The raster is drawn: more than one colour on the canvas.
        assert distinct_colours(page, "phase-map", 97) >= 2
        # Click the cell of mass index 45 (x), gap index 10 (y, drawn upwards).
        box = cv.bounding_box()
        ix, iy = 45, 10
        x = box["x"] + (ix + 0.5) * box["width"] / 60
        y = box["y"] + (40 - 1 - iy + 0.5) * box["height"] / 40
        t1 = time.time()
        page.mouse.click(x, y)
        want = ix * 40 + iy
        details = page.get_by_test_id("scene-details")
        assert details.get_attribute("data-scene-id") == str(want)
        page.get_by_test_id("trace-plot").wait_for(timeout=20_000)
        click_to_trace = time.time() - t1
        row = rows[1 + want].split(",")
        text = details.inner_text()
        assert f"Scene {want}" in text
        # On screen at most 6 significant digits; the full value in the cell's title.
        for name in ("mass[2]", "gap"):
            full = row[header.index(name)]
            assert details.locator(f'td[title="{full}"]').count() >= 1, full
        cells = details.locator("td").all_inner_texts()
        assert cells and all(sig_digits(t) <= 6 for t in cells), cells
        # The trace is drawn (non-blank canvas), the comparison models are there.
        drawn = page.evaluate(
            f"""() => {{ const d = ({PIXELS})('trace-plot');
                       let n = 0; for (let i = 3; i < d.length; i += 4) n += d[i] > 0; return n; }}"""
        )
        assert drawn > 500
        # The diagram's axes: tick labels of position and time, <= 6 digits.
        trace = page.get_by_test_id("trace-plot")
        for a in ("data-x-ticks", "data-y-ticks"):
            labels = [t for t in trace.get_attribute(a).split("|") if not t.startswith("offset")]
            assert len(labels) >= 3 and all(0 < sig_digits(t.lstrip("+")) <= 6 or t.lstrip("+") == "0" for t in labels), (a, labels)
        assert "hard-sphere" in text and "closure" in text
        shot = os.environ.get("EXPLORER_SCREENSHOT", str(ROOT / "results" / "explorer.png"))
        page.screenshot(path=shot)
        assert not errors, errors
        # An invalid request from the page's side (its 404 is logged by the
        # browser): the page shows the error, the server goes on.
        status, body = get(url + "api/scene?id=nope")
        assert status == 400
        page.evaluate("openScene(123456)")
        page.wait_for_function("document.querySelector('[data-testid=scene-details]').innerText.includes('no scene')")
        page.mouse.click(x, y)
        page.get_by_test_id("trace-plot").wait_for(timeout=20_000)
        browser.close()
    print(f"first paint {first_paint:.2f} s, click to trace {click_to_trace:.2f} s")


def test_a_sampled_table_is_drawn_as_points_and_a_click_opens_the_nearest(tmp_path):
    if not Path(CHROMIUM).exists():
        pytest.skip(f"no browser at {CHROMIUM}: apt-get install chromium")
    spec = ("[scene]\nballs = 5\nvelocity = [1.0, 0, 0, 0, 0]\n"
            "[sample]\ndesign = \"lhs\"\npoints = 300\nseed = 2\n"
            "[[axis]]\nparam = \"mass[2]\"\nrange = [0.0064, 0.64]\nscale = \"log\"\n"
            "[[axis]]\nparam = \"gap\"\nrange = [0.0, 2e-5]\n")
    with explorer(tmp_path, "lhs", spec) as (url, _):
        with opened(url) as (page, errors):
            cv = page.get_by_test_id("phase-map")
            assert cv.get_attribute("data-points") == "300"
            pts = page.evaluate("pts")
            px, py, _ = pts[17]
            box = cv.bounding_box()
            page.mouse.click(box["x"] + px, box["y"] + py)
            want = min(pts, key=lambda q: (q[0] - px) ** 2 + (q[1] - py) ** 2)[2]
            details = page.get_by_test_id("scene-details")
            assert details.get_attribute("data-scene-id") == str(int(want))
            page.get_by_test_id("trace-plot").wait_for(timeout=20_000)
            # A dragged box zooms both axes; a double-click shows every point again.
            whole = (cv.get_attribute("data-x-ticks"), cv.get_attribute("data-y-ticks"))
            page.mouse.move(box["x"] + 0.2 * box["width"], box["y"] + 0.2 * box["height"])
            page.mouse.down()
            page.mouse.move(box["x"] + 0.5 * box["width"], box["y"] + 0.5 * box["height"], steps=5)
            page.mouse.up()
            page.wait_for_function(f"document.querySelector('[data-testid=phase-map]').dataset.yTicks !== {whole[1]!r}")
            assert cv.get_attribute("data-x-ticks") != whole[0]
            page.mouse.dblclick(box["x"] + 0.5 * box["width"], box["y"] + 0.5 * box["height"])
            assert (cv.get_attribute("data-x-ticks"), cv.get_attribute("data-y-ticks")) == whole
        assert not errors, errors


def test_a_chain_sweep_opens_a_clicked_chain_as_a_space_time_image(tmp_path):
    """A sweep of granular chains: the map draws, a click runs that chain
    again and shows its bead histories as an image (bead × time)."""
    if not Path(CHROMIUM).exists():
        pytest.skip(f"no browser at {CHROMIUM}: apt-get install chromium")
    spec = ("[scene]\nballs = 120\nradius = 0.005\n[scene.walls]\nright = true\n"
            "[scene.launch]\nballs = 1\nvelocity = 0.1\n[scene.probes]\nbeads = [30, 90]\n"
            "[scene.impurity]\nbeads = [60]\nmass = 1e-3\n[scene.solver]\ntolerance = 1e-4\n"
            "[[axis]]\nparam = \"launch.velocity\"\nvalues = [0.05, 0.1, 0.2]\n"
            "[[axis]]\nparam = \"impurity.mass\"\nlogspace = [1e-4, 1e-2, 3]\n")
    with explorer(tmp_path, "chains", spec) as (url, table):
        rows = table.read_text().splitlines()
        header = rows[0].split(",")
        status, body = get(url + "api/scene?id=4")
        assert status == 200, body
        h = body["histories"]
        assert body["beads"] == 120 and h["beads"][0] == 0 and h["beads"][-1] == 119
        assert len(h["v"]) == len(h["beads"]) and len(h["v"][0]) == len(h["t"]) > 50
        # The run again is the sweep's row.
        assert body["outcome"] == [[k, v] for k, v in zip(header[3:], rows[5].split(",")[3:])]
        with opened(url) as (page, errors):
            cv = page.get_by_test_id("phase-map")
            box = cv.bounding_box()
            # Cell (velocity 1, impurity mass 2): scene 1·3 + 2 = 5.
            page.mouse.click(box["x"] + 1.5 * box["width"] / 3, box["y"] + 0.5 * box["height"] / 3)
            details = page.get_by_test_id("scene-details")
            assert details.get_attribute("data-scene-id") == "5"
            page.get_by_test_id("spacetime-image").wait_for(timeout=20_000)
            colours = distinct_colours(page, "spacetime-image", 7)
            assert colours > 10, colours
            # Axes: bead numbers within 0 ..= 119 up the side, time along the bottom.
            img = page.get_by_test_id("spacetime-image")
            beads = [float(t) for t in img.get_attribute("data-y-ticks").split("|")]
            assert len(beads) >= 3 and all(0 <= b <= 119 for b in beads), beads
            assert len(img.get_attribute("data-x-ticks").split("|")) >= 3
            assert "energy_transmitted" in details.inner_text()
            # The same chain coloured by contact force (>= 0: from white up).
            page.get_by_test_id("select-field").select_option("f")
            page.wait_for_function("document.querySelector('[data-testid=spacetime-image]').dataset.field === 'f'")
            assert distinct_colours(page, "spacetime-image", 7) > 10
            bar = [float(t) for t in page.get_by_test_id("spacetime-colorbar").get_attribute("data-ticks").split("|")]
            assert len(bar) >= 3 and min(bar) == 0, bar
            # The colour bar is its own canvas, painted from white up.
            assert page.evaluate("document.querySelector('[data-testid=spacetime-colorbar]').width") == 12
            assert distinct_colours(page, "spacetime-colorbar", 1) > 10
            page.get_by_test_id("select-field").select_option("v")
            page.wait_for_function("document.querySelector('[data-testid=spacetime-image]').dataset.field === 'v'")
            page.screenshot(path=os.environ.get("EXPLORER_CHAIN_SCREENSHOT", str(ROOT / "results" / "explorer_chain.png")))
        assert not errors, errors


def test_a_shards_rows_are_its_ids_and_an_edited_sweep_is_not_run(tmp_path):
    """A shard's table: row panel and scene of id k are scene k's (not the
    k-th row's); after its sweep file is edited, scenes are refused, naming
    why, instead of running other scenes under the table's rows."""
    spec = tmp_path / "s.toml"
    text = ("[scene]\nballs = 5\nvelocity = [1.0, 0, 0, 0, 0]\n"
            "[[axis]]\nparam = \"mass[2]\"\nlogspace = [0.01, 1.0, 10]\n")
    spec.write_text(text)
    table = tmp_path / "part.csv"
    subprocess.run([cradle_bin(), "sweep", spec, "--out", table, "--backend", "cpu",
                    "--shard", "2/2"], check=True, capture_output=True, cwd=tmp_path)
    with serving(tmp_path, table) as url:
        status, body = get(url + "api/row?id=7")
        assert status == 200 and body["row"][0] == ["id", "7"], body
        row = dict(body["row"])
        status, scene = get(url + "api/scene?id=7")
        assert status == 200, scene
        outcome = dict(scene["outcome"])
        assert scene["id"] == 7 and outcome["ejected"] == row["ejected"], (outcome, row)
        status, body = get(url + "api/row?id=2")
        assert status == 404 and "no scene 2" in body["error"], body
    spec.write_text(text.replace("1.0, 10]", "2.0, 10]"))
    with serving(tmp_path, table) as url:
        status, body = get(url + "api/scene?id=7")
        assert status == 404 and "changed since this table was made" in body["error"], body
        status, body = get(url + "api/row?id=7")
        assert status == 200 and body["row"][0] == ["id", "7"], body


def test_the_map_has_ticks_a_colour_bar_and_zooms(server):
    """Axes with tick labels (values of the axis, log for mass[2], at most 6
    significant digits), a colour bar (categories for `ejected`, a scale for
    a continuous column), wheel and box zoom shown in data-x-range /
    data-y-range and in the ticks, a double-click back to the whole map."""
    if not Path(CHROMIUM).exists():
        pytest.skip(f"no browser at {CHROMIUM}: apt-get install chromium")
    url, _ = server
    with opened(url) as (page, errors):
        ticks = lambda testid: page.get_by_test_id(testid).locator(".tick").all_inner_texts()
        xs, ys = ticks("x-axis"), ticks("y-axis")
        assert len(xs) >= 3 and len(ys) >= 3, (xs, ys)
        assert all(sig_digits(t) <= 6 for t in xs + ys), (xs, ys)
        xv, yv = [float(t) for t in xs], [float(t) for t in ys]
        assert all(0.0064 <= v <= 0.64 for v in xv) and xv == sorted(xv), xs
        assert all(0 <= v <= 2e-5 for v in yv) and yv == sorted(yv), ys
        # Hovering a cell: a tooltip with its x, y and colour value (6 digits).
        cv = page.get_by_test_id("phase-map")
        box = cv.bounding_box()
        page.mouse.move(box["x"] + 12.5 * box["width"] / 60, box["y"] + (40 - 1 - 30 + 0.5) * box["height"] / 40)
        tip = page.get_by_test_id("map-tooltip")
        tip.wait_for(timeout=5_000)
        # "name = short" or "name = short  (full)": 6 digits, and all 17 when 6 lose some.
        lines = dict(l.split(" = ") for l in tip.inner_text().splitlines())
        assert set(lines) == {"mass[2]", "gap", "ejected"}, lines
        short = {k: v.split()[0] for k, v in lines.items()}
        full = {k: float(v.split()[-1].strip("()")) for k, v in lines.items()}
        assert abs(float(short["mass[2]"]) / (0.0064 * 100 ** (12 / 59)) - 1) < 1e-5, lines
        assert abs(full["mass[2]"] / (0.0064 * 100 ** (12 / 59)) - 1) < 1e-13, lines
        assert abs(full["gap"] / (30 * 2e-5 / 39) - 1) < 1e-13 and short["ejected"] in ("1", "2"), lines
        assert all(sig_digits(v) <= 6 for v in short.values()), lines
        bar = page.get_by_test_id("colorbar")
        assert bar.get_attribute("data-kind") == "categorical"
        page.get_by_test_id("select-colour").select_option(label="energy_left")
        page.wait_for_function("document.querySelector('[data-testid=colorbar]').dataset.kind === 'continuous'")
        # energy_left spans ~1e-3 below 1: labels distinct (with an offset if needed).
        labels = page.locator("#cbticks .tick").all_inner_texts()
        assert len(labels) >= 3 and len(set(labels)) == len(labels), labels
        # A log colour scale for a positive column spanning decades (energy_error).
        page.get_by_test_id("select-colour").select_option(label="energy_error")
        page.wait_for_function("document.querySelector('#cbticks .tick') !== null")
        assert bar.get_attribute("data-scale") == "linear"
        page.get_by_test_id("log-colour").check()
        page.wait_for_function("document.querySelector('[data-testid=colorbar]').dataset.scale === 'log'")
        logs = [float(t) for t in page.locator("#cbticks .tick").all_inner_texts()]
        assert len(logs) >= 2 and all(v > 0 for v in logs), logs
        page.get_by_test_id("log-colour").uncheck()
        page.get_by_test_id("select-colour").select_option(label="energy_left")
        page.wait_for_function("document.querySelector('[data-testid=colorbar]').dataset.scale === 'linear'")
        cv = page.get_by_test_id("phase-map")
        span = lambda a: (lambda lo, hi: hi - lo)(*map(float, cv.get_attribute(a).split(",")))
        whole = (cv.get_attribute("data-x-range"), cv.get_attribute("data-y-range"))
        assert abs(float(whole[0].split(",")[0]) - 0.0064) < 1e-3, whole
        box = cv.bounding_box()
        page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        page.mouse.wheel(0, -400)
        page.wait_for_function(f"document.querySelector('[data-testid=phase-map]').dataset.xRange !== {whole[0]!r}")
        assert span("data-y-range") < float(whole[1].split(",")[1])
        page.mouse.dblclick(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        assert (cv.get_attribute("data-x-range"), cv.get_attribute("data-y-range")) == whole
        # A box from 20% to 50% of the width and height.
        page.mouse.move(box["x"] + 0.2 * box["width"], box["y"] + 0.2 * box["height"])
        page.mouse.down()
        page.mouse.move(box["x"] + 0.35 * box["width"], box["y"] + 0.35 * box["height"], steps=4)
        page.mouse.move(box["x"] + 0.5 * box["width"], box["y"] + 0.5 * box["height"], steps=4)
        page.mouse.up()
        lo, hi = map(float, cv.get_attribute("data-y-range").split(","))
        assert 0.45 * 2e-5 < lo < hi < 0.85 * 2e-5, (lo, hi)
        assert ticks("y-axis") != ys
        page.screenshot(path=os.environ.get("EXPLORER_ZOOM_SCREENSHOT", str(ROOT / "results" / "explorer_zoom.png")))
        # A click: the colour column along x through that cell (slice plot),
        # and two scenes compared (pin one, open another).
        page.mouse.dblclick(box["x"] + 5, box["y"] + 5)
        cell = lambda ix, iy: (box["x"] + (ix + 0.5) * box["width"] / 60,
                               box["y"] + (40 - 1 - iy + 0.5) * box["height"] / 40)
        page.mouse.click(*cell(12, 30))
        details = page.get_by_test_id("scene-details")
        page.wait_for_function("document.querySelector('[data-testid=scene-details]').dataset.sceneId === String(12 * 40 + 30)")
        sl = page.get_by_test_id("slice-plot")
        assert sl.is_visible() and sl.get_attribute("data-points") == "60" and sl.get_attribute("data-at") == "12"
        assert distinct_colours(page, "slice-plot", 7) >= 3
        page.locator("#pin").click()
        page.mouse.click(*cell(40, 5))
        cmp = page.get_by_test_id("compare")
        cmp.wait_for(timeout=20_000)
        heads = cmp.locator("tr").first.inner_text()
        assert "scene 510 (pinned)" in heads and "scene 1605" in heads, heads
        differs = cmp.locator("tr.differs th").all_inner_texts()
        assert "mass[2]" in differs and "gap" in differs and "id" in differs, differs
        assert sl.get_attribute("data-at") == "40"
        page.screenshot(path=os.environ.get("EXPLORER_COMPARE_SCREENSHOT", str(ROOT / "results" / "explorer_compare.png")))
        # Brushing: a drag along the slice plot's x highlights the map's
        # cells in that range of mass[2] — whole columns (40 cells each) —
        # a box also limits the value; a click on the plot clears it.
        sb = sl.bounding_box()
        page.mouse.move(sb["x"] + 0.2 * sb["width"], sb["y"] + 0.5 * sb["height"])
        page.mouse.down()
        page.mouse.move(sb["x"] + 0.4 * sb["width"], sb["y"] + 0.5 * sb["height"], steps=4)
        page.mouse.move(sb["x"] + 0.6 * sb["width"], sb["y"] + 0.5 * sb["height"], steps=4)
        page.mouse.up()
        page.wait_for_function("document.querySelector('[data-testid=phase-map]').dataset.brushed !== undefined")
        columns = int(sl.get_attribute("data-brush-cells"))
        lo, hi = map(float, sl.get_attribute("data-brush").split(","))
        # mass[2] is logspace(0.0064, 0.64, 60): the columns inside [lo, hi].
        inside = [k for k in range(60) if lo <= 0.0064 * 100 ** (k / 59) <= hi]
        assert 15 <= columns <= 30 and columns == len(inside), (columns, lo, hi)
        assert int(cv.get_attribute("data-brushed")) == 40 * columns
        page.screenshot(path=os.environ.get("EXPLORER_BRUSH_SCREENSHOT", str(ROOT / "results" / "explorer_brush.png")))
        page.mouse.move(sb["x"] + 0.3 * sb["width"], sb["y"] + 0.1 * sb["height"])
        page.mouse.down()
        page.mouse.move(sb["x"] + 0.5 * sb["width"], sb["y"] + 0.5 * sb["height"], steps=4)
        page.mouse.move(sb["x"] + 0.7 * sb["width"], sb["y"] + 0.9 * sb["height"], steps=4)
        page.mouse.up()
        page.wait_for_function(f"document.querySelector('[data-testid=slice-plot]').dataset.brush !== '{lo},{hi}'")
        assert int(cv.get_attribute("data-brushed")) <= 40 * int(sl.get_attribute("data-brush-cells"))
        page.mouse.click(sb["x"] + 0.5 * sb["width"], sb["y"] + 0.5 * sb["height"])
        page.wait_for_function("document.querySelector('[data-testid=phase-map]').dataset.brushed === undefined")
        assert not errors, errors


def test_an_exported_scene_runs_to_its_row_and_a_table_finds_its_sweep_beside_it(tmp_path):
    """The exported scene TOML carries the sweep's --method/--tolerance, so
    `cradle run` on it gives the table's row (it left them out); a table
    explored from its own folder finds the sweep file beside it (the
    sidecar names it as the sweep ran, from the folder above)."""
    run = tmp_path / "run"
    run.mkdir()
    (run / "s.toml").write_text("[scene]\nballs = 5\nvelocity = [1.0, 0, 0, 0, 0]\n"
                                "[[axis]]\nparam = \"mass[2]\"\nlogspace = [0.01, 1.0, 6]\n")
    subprocess.run([cradle_bin(), "sweep", "run/s.toml", "--out", "run/t.csv", "--backend", "cpu",
                    "--method", "verlet", "--tolerance", "1e-4"], check=True, capture_output=True,
                   cwd=tmp_path)
    rows = list(csv.DictReader(open(run / "t.csv")))
    with serving(run, run / "t.csv") as url:
        status, meta = get(url + "api/meta")
        assert status == 200 and meta["scenes"], meta
        with urllib.request.urlopen(url + "api/scene.toml?id=3", timeout=30) as r:
            text = r.read().decode()
    assert 'method = "verlet"' in text and "tolerance = 0.0001" in text, text
    scene = tmp_path / "scene3.toml"
    scene.write_text(text)
    out = subprocess.run([cradle_bin(), "run", scene, "--format", "csv"], check=True,
                         capture_output=True, text=True).stdout
    mine = next(csv.DictReader(io.StringIO(out)))
    for k in ["v_0", "v_1", "v_2", "v_3", "v_4", "steps", "ejected"]:
        assert mine[k] == rows[3][k], (k, mine[k], rows[3][k])


def test_an_optimisation_shows_its_convergence_and_opens_a_candidate(tmp_path):
    """`cradle optimize`'s table: its sidecar names the problem file; the
    page draws the candidates (first two variables, coloured by the
    objective) and the convergence (best feasible objective against
    evaluations); a candidate's scene runs again to its row; after the
    problem file is edited, scenes are refused, naming why."""
    problem = tmp_path / "p.toml"
    problem.write_text(
        "[scene]\nballs = 8\nradius = 0.005\n[scene.walls]\nright = true\n"
        "[scene.launch]\nballs = 1\nvelocity = 1.0\n[scene.probes]\nbeads = [7]\n"
        "[scene.stop]\nduration = 2e-3\n"
        "[[variable]]\nname = \"radius[1..3]\"\nmin = 0.002\nmax = 0.008\nscale = \"log\"\n"
        "[[variable]]\nname = \"young_modulus[4]\"\nchoices = [200e9, 3e9]\n"
        "[objective]\nminimize = \"wall_right_peak_force\"\n"
        "[[constraint]]\nexpr = \"total_mass <= 0.04\"\n"
        "[optimizer]\npopulation = 8\nevaluations = 48\nseed = 3\n")
    table = tmp_path / "runs.csv"
    subprocess.run([cradle_bin(), "optimize", problem.name, "--out", table.name, "--backend", "cpu"],
                   check=True, capture_output=True, cwd=tmp_path)
    sidecar = json.loads((tmp_path / "runs.csv.json").read_text())
    assert sidecar["sweep_file"] == "p.toml" and sidecar["table"]["rows"] == 48
    assert sidecar["sweep"]["optimize"]["objective"] == "wall_right_peak_force"
    rows = list(csv.DictReader(io.StringIO(table.read_text())))
    feasible = [float(r["wall_right_peak_force"]) for r in rows if r["feasible"] == "true"]
    assert feasible, "no feasible candidate: the test's problem needs another bound"
    with serving(tmp_path, table) as url:
        status, meta = get(url + "api/meta")
        assert status == 200 and meta["scenes"] is True, meta
        assert meta["optimize"]["variables"] == ["radius[1]", "radius[2]", "radius[3]", "young_modulus[4]"]
        # Candidate 13 (generation 1, candidate 5) runs again to its row.
        status, body = get(url + "api/scene?id=13")
        assert status == 200, body
        assert all(rows[13][k] == v for k, v in body["outcome"]), (body["outcome"], rows[13])
        with opened(url) as (page, errors):
            conv = page.get_by_test_id("convergence")
            assert conv.get_attribute("data-evaluations") == "48"
            assert float(conv.get_attribute("data-best")) == min(feasible)
            cv = page.get_by_test_id("phase-map")
            assert cv.get_attribute("data-points") == "48"
            px, py, want = page.evaluate("pts")[20]
            box = cv.bounding_box()
            page.mouse.click(box["x"] + px, box["y"] + py)
            details = page.get_by_test_id("scene-details")
            page.wait_for_function("document.querySelector('[data-testid=scene-details]').dataset.sceneId !== ''")
            near = min(page.evaluate("pts"), key=lambda q: (q[0] - px) ** 2 + (q[1] - py) ** 2)[2]
            assert details.get_attribute("data-scene-id") == str(int(near))
            page.get_by_test_id("spacetime-image").wait_for(timeout=20_000)
        assert not errors, errors
    problem.write_text(problem.read_text().replace("seed = 3", "seed = 4"))
    with serving(tmp_path, table) as url:
        status, meta = get(url + "api/meta")
        assert meta["scenes"] is False and "changed since this table was made" in meta["scenes_problem"]
        status, body = get(url + "api/scene?id=13")
        assert status == 404 and "changed since" in body["error"], body
