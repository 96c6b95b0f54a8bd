#!/usr/bin/python3
"""Statistics of a PNG for the figure tests: is it a drawn figure, not a blank page?

usage: png_stats.py [--rows] FILE [#rrggbb ...]
prints JSON: width, height, distinct colours, the fraction of pixels that differ from the most common
(background) colour, and for each colour asked the number of pixels within 8 levels of it per channel.
With --rows also "rows": for each colour asked, the 5th and 95th percentiles of its pixels' row indices
(top = 0; null without pixels): how far a curve spans vertically, a legend sample aside.
"""
import json
import sys

from PIL import Image  # Debian python3-pil (scripts/setup.sh)


def near(c, want):
    return all(abs(a - b) <= 8 for a, b in zip(c, want))


def main():
    args = sys.argv[1:]
    rows = args[:1] == ["--rows"]
    if rows:
        args = args[1:]
    img = Image.open(args[0]).convert("RGB")
    w, h = img.size
    counts = img.getcolors(maxcolors=w * h)
    counts.sort(reverse=True)
    background = counts[0][1]
    non_bg = sum(n for n, c in counts if c != background)
    out = {"width": w, "height": h, "distinct": len(counts), "non_background": non_bg / float(w * h), "colours": {}}
    wants = {h: tuple(int(h[i:i + 2], 16) for i in (1, 3, 5)) for h in args[1:]}
    for hex_colour, want in wants.items():
        out["colours"][hex_colour] = sum(n for n, c in counts if near(c, want))
    if rows:
        found = {h: [] for h in wants}
        for k, c in enumerate(img.getdata()):
            for h, want in wants.items():
                if near(c, want):
                    found[h].append(k // w)
        out["rows"] = {}
        for h, r in found.items():
            r.sort()
            out["rows"][h] = [r[len(r) // 20], r[(len(r) * 19) // 20]] if r else None
    print(json.dumps(out))


if __name__ == "__main__":
    main()
