#!/usr/bin/python3
"""`fleetgw ride plot` seen by a browser: the SVG rendered by headless Chromium.

Usage: render_ride_plot.py FIXTURE FLEETGW [KEEP_DIR]
  FIXTURE   the ride_plot_fixture program (writes the test store, tests/config/ride_plot_store.h)
  FLEETGW   the fleetgw binary
  KEEP_DIR  where ride_plot.svg and ride_plot.png are left for a human to look at

Writes the store, plots its latest ride (the one with a hostile id: markup that would end the
document if it were not escaped) with the real binary, parses the SVG as XML (Python's
standard library), renders it with `chromium --headless --screenshot`, decodes the PNG with
zlib + struct (no PIL) and checks that the screenshot is not blank (many distinct colours, the
four series colours present), that every axis line the SVG declares (<line class="axis
...">) is a long run of dark pixels at its position, and that the ride's GNSS track is drawn in
the map panel (<g id="panel-map">): many pixels of the track colour inside the panel's frame,
none in the time panels above it. Exit 77 (ctest SKIP_RETURN_CODE) when chromium is not
installed; every other problem fails.
"""

import os
import shutil
import struct
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
import zlib

SKIP = 77
SVG_NS = "{http://www.w3.org/2000/svg}"
SERIES_COLOURS = {"speed": (0x1F, 0x77, 0xB4), "power": (0xD6, 0x27, 0x28),
                  "soc": (0x2C, 0xA0, 0x2C), "assist": (0x94, 0x67, 0xBD)}
TRACK_COLOUR = (0xFF, 0x7F, 0x0E)  # kTrackColour, gateway/tools/plot/ride_plot_map.h


def fail(message):
    print("render_ride_plot: FAIL: " + message, file=sys.stderr)
    sys.exit(1)


def decode_png(data):
    """(width, height, rows): rows[y][x] = (r, g, b); 8-bit RGB, RGBA, grey or grey+alpha."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        fail("not a PNG")
    pos, idat, header = 8, [], None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
    if header is None:
        fail("PNG without IHDR")
    width, height, depth, colour, _, _, interlace = header
    channels = {0: 1, 2: 3, 4: 2, 6: 4}.get(colour)
    if depth != 8 or channels is None or interlace != 0:
        fail(f"unsupported PNG: depth {depth}, colour type {colour}, interlace {interlace}")
    raw = zlib.decompress(b"".join(idat))
    stride = width * channels
    rows, previous = [], bytearray(stride)
    for y in range(height):
        start = y * (stride + 1)
        kind, line = raw[start], bytearray(raw[start + 1:start + 1 + stride])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b = previous[i]
            c = previous[i - channels] if i >= channels else 0
            if kind == 1:
                line[i] = (line[i] + a) & 0xFF
            elif kind == 2:
                line[i] = (line[i] + b) & 0xFF
            elif kind == 3:
                line[i] = (line[i] + ((a + b) >> 1)) & 0xFF
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 0xFF
            elif kind != 0:
                fail(f"bad PNG filter {kind} in row {y}")
        previous = line
        if channels >= 3:
            rows.append([tuple(line[x * channels:x * channels + 3]) for x in range(width)])
        else:
            rows.append([(line[x * channels],) * 3 for x in range(width)])
    return width, height, rows


def is_dark(pixel):
    return max(pixel) < 110


def near(pixel, colour, tolerance=40):
    return all(abs(p - c) <= tolerance for p, c in zip(pixel, colour))


def main():
    if len(sys.argv) not in (3, 4):
        print(__doc__, file=sys.stderr)
        return 2
    fixture, fleetgw = sys.argv[1], sys.argv[2]
    keep = sys.argv[3] if len(sys.argv) == 4 else None
    chromium = shutil.which("chromium")
    if chromium is None:
        print("render_ride_plot: SKIP: chromium is not installed "
              "(apt-get install --no-install-recommends chromium)")
        return SKIP

    work = tempfile.mkdtemp(prefix="fleetgw-ride-render-")
    profile = tempfile.mkdtemp(prefix="fleetgw-chromium-")
    try:
        store, svg, png = (os.path.join(work, n) for n in ("ride.db", "ride.svg", "ride.png"))
        subprocess.run([fixture, store], check=True, timeout=60)
        plotted = subprocess.run([fleetgw, "ride", "plot", "latest", "--db", store, "--out", svg],
                                 capture_output=True, text=True, timeout=60)
        if plotted.returncode != 0:
            fail(f"fleetgw ride plot exited {plotted.returncode}: {plotted.stderr}")

        # Well-formed XML, and where the axes are.
        try:
            root = ET.parse(svg).getroot()
        except ET.ParseError as e:
            fail(f"the SVG is not well-formed XML: {e}")
        if root.tag != SVG_NS + "svg":
            fail(f"root element {root.tag}")
        width, height = int(root.get("width")), int(root.get("height"))
        title = root.find(SVG_NS + "title")
        if title is None or "<script>" not in (title.text or ""):
            fail("the hostile ride id is not in the title as text")
        axes = [e for e in root.iter(SVG_NS + "line") if "axis" in e.get("class", "").split()]
        if len(axes) < 8:
            fail(f"{len(axes)} axis lines in the SVG, expected 8 (4 panels)")
        # The fixture's latest ride has a track: the map panel, its frame and the polyline.
        panel = next((g for g in root.iter(SVG_NS + "g") if g.get("id") == "panel-map"), None)
        if panel is None:
            fail("no map panel (<g id=\"panel-map\">) for a ride with a track")
        frame = next((r for r in panel.iter(SVG_NS + "rect") if r.get("class") == "map-frame"),
                     None)
        track = next((p for p in panel.iter(SVG_NS + "polyline") if p.get("class") == "track"),
                     None)
        if frame is None or track is None:
            fail("the map panel has no frame or no track polyline")
        fx, fy, fw, fh = (float(frame.get(k)) for k in ("x", "y", "width", "height"))

        command = [chromium, "--headless", "--no-sandbox", "--disable-gpu",
                   "--disable-background-networking", "--disable-component-update",
                   "--disable-sync", "--no-first-run", "--disable-dev-shm-usage",
                   "--force-device-scale-factor=1", "--hide-scrollbars",
                   "--user-data-dir=" + profile, "--screenshot=" + png,
                   f"--window-size={width},{height}", "file://" + svg]
        shot = subprocess.run(command, capture_output=True, text=True, timeout=180)
        if shot.returncode != 0 or not os.path.exists(png):
            fail(f"chromium exited {shot.returncode} without a screenshot: {shot.stderr[-2000:]}")
        if keep:
            shutil.copy(svg, os.path.join(keep, "ride_plot.svg"))
            shutil.copy(png, os.path.join(keep, "ride_plot.png"))

        with open(png, "rb") as f:
            w, h, rows = decode_png(f.read())
        if (w, h) != (width, height):
            fail(f"screenshot is {w}x{h}, expected {width}x{height}")

        # Not blank: many colours, ink on a good part of the page, every series drawn.
        colours = {}
        for row in rows:
            for p in row:
                colours[p] = colours.get(p, 0) + 1
        ink = sum(n for p, n in colours.items() if min(p) < 235)
        if len(colours) < 30:
            fail(f"only {len(colours)} distinct colours: blank or an error page")
        if ink < 0.01 * w * h:
            fail(f"only {ink} non-white pixels")
        for name, colour in SERIES_COLOURS.items():
            seen = sum(n for p, n in colours.items() if near(p, colour))
            if seen < 100:
                fail(f"the {name} series is missing ({seen} pixels of its colour)")

        # The track: drawn inside the map's frame (a 3-pixel line several hundred pixels long),
        # and its colour nowhere in the time panels above the map.
        inside = sum(1 for y in range(int(fy), min(h, int(fy + fh)))
                     for x in range(int(fx), min(w, int(fx + fw))) if near(rows[y][x], TRACK_COLOUR))
        above = sum(1 for y in range(0, int(fy) - 30) for x in range(w)
                    if near(rows[y][x], TRACK_COLOUR))
        if inside < 1000:
            fail(f"the track is missing from the map panel ({inside} pixels of its colour)")
        if above > 0:
            fail(f"{above} pixels of the track colour above the map panel")

        # Every axis: at least 95 % of its length dark, within a pixel of where the SVG puts it.
        for e in axes:
            x1, y1, x2, y2 = (float(e.get(k)) for k in ("x1", "y1", "x2", "y2"))
            if x1 == x2:
                cols = [c for c in (int(x1) - 1, int(x1)) if 0 <= c < w]
                span = range(int(min(y1, y2)) + 1, int(max(y1, y2)) - 1)
                dark = sum(1 for y in span if any(is_dark(rows[y][c]) for c in cols))
                where = f"x = {x1}, y {y1}..{y2}"
            else:
                lines = [r for r in (int(y1) - 1, int(y1)) if 0 <= r < h]
                span = range(int(min(x1, x2)) + 1, int(max(x1, x2)) - 1)
                dark = sum(1 for x in span if any(is_dark(rows[r][x]) for r in lines))
                where = f"y = {y1}, x {x1}..{x2}"
            if len(span) < 50 or dark < 0.95 * len(span):
                fail(f"axis {e.get('class')} at {where}: {dark} of {len(span)} pixels dark")
        # Outside the plots (the right margin) the page is white: the axes are not everywhere.
        margin = [rows[y][w - 5] for y in range(h)]
        if any(is_dark(p) for p in margin):
            fail("dark pixels in the right margin")
        print(f"render_ride_plot: OK: {w}x{h}, {len(colours)} colours, {len(axes)} axes dark, "
              f"{inside} track pixels in the map")
        return 0
    finally:
        shutil.rmtree(work, ignore_errors=True)
        shutil.rmtree(profile, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
