#!/usr/bin/python3
"""Statistics of a PNG for the figure tests: is it a drawn figure, not a blank page?

usage: png_stats.py FILE [#rrggbb ...]
prints JSON: width, height, distinct colours, the fraction of pixels that differ from the most common
(background) colour, and for each colour asked the number of pixels within 8 levels of it per channel.
"""
import json
import sys

from PIL import Image  # Debian python3-pil (scripts/setup.sh)


def main():
    img = Image.open(sys.argv[1]).convert("RGB")
    w, h = img.size
    counts = img.getcolors(maxcolors=w * h)
    counts.sort(reverse=True)
    background = counts[0][1]
    non_bg = sum(n for n, c in counts if c != background)
    out = {"width": w, "height": h, "distinct": len(counts), "non_background": non_bg / float(w * h), "colours": {}}
    for hex_colour in sys.argv[2:]:
        want = tuple(int(hex_colour[i:i + 2], 16) for i in (1, 3, 5))
        out["colours"][hex_colour] = sum(n for n, c in counts if all(abs(a - b) <= 8 for a, b in zip(c, want)))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
