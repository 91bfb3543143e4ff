#!/usr/bin/env python3
"""A flame graph (SVG) from `perf script` output, for docs/images/ (issue 26's profiles).

    perf record -e cpu-clock -F 1000 --call-graph dwarf,16384 -o perf.data -- COMMAND
    perf script -i perf.data | tools/flamegraph.py --title "sparse VO" \
        --root SparseVo::ProcessFrame > docs/images/x.svg

(Release builds have no frame pointers: take the call graphs from DWARF as above.)

Stacks are folded root first (one line per distinct stack with its sample count; --folded
writes those lines instead of the SVG). Each box is a function, its width the share of samples
whose stack passes through it; boxes above it are what it called. Frames narrower than
--min-width of the total are left out. Colours are a hash of the function name (warm for ours,
cool for libraries), so a function has the same colour in every graph.
"""

import argparse
import collections
import hashlib
import html
import re
import sys

# A stack frame line of `perf script`: "\t    55d0c2a1b2c3 Function(args)+0x1f (/path/lib.so)".
FRAME = re.compile(r"^\s+[0-9a-f]+\s+(?P<sym>.+?)(?:\+0x[0-9a-f]+)?\s+\((?P<dso>[^)]*)\)\s*$")


def fold(lines, keep_args):
    """Returns {stack (tuple, root first): samples} from perf script lines."""
    stacks = collections.Counter()
    frames = []
    comm = None
    for line in lines:
        line = line.rstrip("\n")
        if not line.strip():
            if frames:
                stacks[tuple([comm] + frames[::-1])] += 1
            frames, comm = [], None
            continue
        if not line[0].isspace():  # the sample's header: "comm pid/tid time: period event:"
            comm = line.split()[0]
            continue
        m = FRAME.match(line)
        if not m:
            continue
        sym = m.group("sym")
        if sym == "[unknown]":
            sym = "[" + m.group("dso").rsplit("/", 1)[-1] + "]"
        elif not keep_args:
            sym = strip_args(sym)
        frames.append(sym)
    if frames:
        stacks[tuple([comm] + frames[::-1])] += 1
    return stacks


def strip_args(sym):
    """mav::Foo::Bar(int, std::vector<...>) const -> mav::Foo::Bar (templates kept)."""
    sym = sym.replace("(anonymous namespace)", "{anon}")
    depth = 0
    for i, c in enumerate(sym):
        if c == "<":
            depth += 1
        elif c == ">":
            depth -= 1
        elif c == "(" and depth == 0 and i > 0 and not sym.startswith("operator()", max(0, i - 8)):
            return sym[:i]
    return sym


def colour(name):
    h = int(hashlib.md5(name.encode()).hexdigest()[:6], 16)
    if "mav::" in name:  # ours: warm
        return "rgb(%d,%d,%d)" % (205 + h % 50, 80 + (h >> 8) % 110, 30 + (h >> 16) % 40)
    return "rgb(%d,%d,%d)" % (60 + h % 60, 130 + (h >> 8) % 70, 170 + (h >> 16) % 70)  # cool


def build_tree(stacks):
    root = {"name": "all", "value": 0, "children": {}}
    for stack, n in stacks.items():
        root["value"] += n
        node = root
        for name in stack:
            child = node["children"].setdefault(name, {"name": name, "value": 0, "children": {}})
            child["value"] += n
            node = child
    return root


def depth_of(node):
    return 1 + max((depth_of(c) for c in node["children"].values()), default=0)


def svg(root, title, width, min_width):
    row = 16
    total = root["value"]
    depth = depth_of(root)
    height = (depth + 3) * row
    out = [
        '<?xml version="1.0" standalone="no"?>',
        '<svg version="1.1" width="%d" height="%d" xmlns="http://www.w3.org/2000/svg" '
        'font-family="Verdana" font-size="11">' % (width, height),
        '<rect x="0" y="0" width="%d" height="%d" fill="#f8f8f8"/>' % (width, height),
        '<text x="%d" y="16" text-anchor="middle" font-size="14">%s (%d samples)</text>'
        % (width // 2, html.escape(title), total),
    ]
    scale = (width - 20) / max(total, 1)

    def draw(node, x, level):
        w = node["value"] * scale
        if node["value"] < min_width * total:
            return
        y = height - (level + 1) * row - 4
        share = 100.0 * node["value"] / total
        label = "%s (%.1f%%)" % (node["name"], share)
        out.append(
            '<g><title>%s</title><rect x="%.1f" y="%d" width="%.1f" height="%d" fill="%s" '
            'rx="2"/>' % (html.escape(label), x, y, max(w - 0.5, 0.1), row - 1, colour(node["name"]))
        )
        chars = int(w / 6.5)
        if chars >= 4:
            text = label if len(label) <= chars else label[: chars - 2] + ".."
            out.append('<text x="%.1f" y="%d">%s</text>' % (x + 3, y + row - 4, html.escape(text)))
        out.append("</g>")
        cx = x
        for child in sorted(node["children"].values(), key=lambda c: c["name"]):
            draw(child, cx, level + 1)
            cx += child["value"] * scale

    draw(root, 10, 0)
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--title", default="CPU profile")
    parser.add_argument("--width", type=int, default=1200)
    parser.add_argument("--min-width", type=float, default=0.002, help="fraction of all samples")
    parser.add_argument("--folded", action="store_true", help="write folded stacks, not SVG")
    parser.add_argument("--keep-args", action="store_true", help="keep argument lists")
    parser.add_argument("--root", default="",
                        help="keep only samples under the first frame containing this text, "
                        "drawn from that frame up (e.g. SparseVo::ProcessFrame)")
    args = parser.parse_args()
    stacks = fold(sys.stdin, args.keep_args)
    if args.root:
        rooted = collections.Counter()
        for stack, n in stacks.items():
            at = next((i for i, f in enumerate(stack) if args.root in f), None)
            if at is not None:
                rooted[stack[at:]] += n
        stacks = rooted
    if not stacks:
        print("flamegraph.py: no stacks in the input (perf script output expected)", file=sys.stderr)
        return 1
    if args.folded:
        for stack, n in sorted(stacks.items()):
            print("%s %d" % (";".join(stack), n))
        return 0
    sys.stdout.write(svg(build_tree(stacks), args.title, args.width, args.min_width))
    return 0


if __name__ == "__main__":
    sys.exit(main())
