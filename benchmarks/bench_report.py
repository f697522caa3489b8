"""Benchmark: how fast a sweep's report opens in Chromium, and how fast zooming loads a full image.

Drives Debian's chromium through Playwright (never downloads a browser) on a report that
``hzval sweep`` wrote: the load event, the images decoded by then, the first frame's images
once scrolled to (previews for images above 2048 px), and the full-resolution file that zooming
to 1x loads for a view on screen. Prints any page error or failed request.

Usage::

    python benchmarks/bench_report.py REPORT_DIR/index.html
"""

import argparse
import sys
import time
from pathlib import Path

CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-background-networking",
]


def main(index: str) -> None:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        page = b.new_page(viewport={"width": 1440, "height": 900})
        errors = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.on("requestfailed", lambda r: errors.append("failed " + r.url))
        t0 = time.perf_counter()
        page.goto(Path(index).as_uri(), wait_until="load")
        t_load = time.perf_counter() - t0
        imgs = page.eval_on_selector_all(
            "img", "els => els.map(e => [e.getAttribute('src'), e.complete, e.naturalWidth])"
        )
        loaded = [i for i in imgs if i[1] and i[2] > 0]
        print(
            f"load event {t_load:.2f} s; {len(imgs)} images, {len(loaded)} decoded at load; widths "
            f"{sorted(set(i[2] for i in loaded))}"
        )
        target = page.locator("#frame-0 .flip[data-own='approx'] img")
        t0 = time.perf_counter()
        target.scroll_into_view_if_needed()
        page.wait_for_function(
            "e => e.complete && e.naturalWidth > 0", arg=target.element_handle(), timeout=60000
        )
        shown = page.eval_on_selector_all(
            "#frame-0 img", "els => els.filter(e => e.complete && e.naturalWidth > 0).length"
        )
        print(
            f"first frame's previews in {time.perf_counter() - t0:.2f} s after scrolling to it ({shown} "
            f"decoded, width {target.evaluate('e => e.naturalWidth')})"
        )
        t0 = time.perf_counter()
        page.locator("button[data-zoom='1']").click()
        page.wait_for_function(
            "e => e.complete && e.naturalWidth > 2000", arg=target.element_handle(), timeout=60000
        )
        print(
            f"zoom 1x: full image {target.evaluate('e => e.naturalWidth')} px in "
            f"{time.perf_counter() - t0:.2f} s; width on screen {target.bounding_box()['width']:.0f}"
        )
        page.keyboard.press("0")
        print("errors", errors)
        b.close()


def cli(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("index", metavar="REPORT_DIR/index.html", help="the report page a sweep wrote")
    args = ap.parse_args(argv)
    index = Path(args.index).resolve()
    if not index.is_file():
        print(f"bench_report: {args.index}: no such file", file=sys.stderr)
        return 2
    main(str(index))
    return 0


if __name__ == "__main__":
    sys.exit(cli())
