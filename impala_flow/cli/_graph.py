"""``impala-flow graph GRAPH``: the graph as Graphviz DOT text, or drawn as a PNG picture.

The picture needs no Graphviz: matplotlib draws the components left to right in graph
order (topological generations of the non-delayed connections), one box per component
with its id, its type and its ports; an arrow per connection from output port to input
port; delayed connections dashed, routed below the graph.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

from .._build import to_dot
from .._component import Source
from .._network import Network
from . import EXIT_FAILED, EXIT_USAGE, CommandError
from .helpers import add_graph_args, check_output_over_inputs, check_writable_file, load_spec, open_session

#: resolution bounds of --png (a picture of a few inches: 10^5 dpi would be gigabytes)
MIN_DPI, MAX_DPI = 10, 1200

__all__ = ["add_parser", "run", "draw_png", "layout"]

EPILOG = """\
examples:
  impala-flow graph my_graph.yaml                  DOT text on stdout
  impala-flow graph my_graph.yaml | dot -Tsvg > g.svg   (if Graphviz is installed)
  impala-flow graph my_graph.yaml --png g.png      a picture, drawn with matplotlib
  impala-flow graph my_graph.yaml --png g.png --dot > g.dot   both
  impala-flow graph graphs/frontend.yaml --var mission=out/beynes.mcap --png g.png
                                                   a replay graph: its mission gives the replayer's ports

In the picture components run left to right in graph order; inputs are on the left of a
box, outputs on the right; dashed arrows are delayed connections ('a.out -> b.in [delay]').
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "graph", help="show a graph as DOT text or a PNG picture",
        description="Load and validate GRAPH, then print it as Graphviz DOT text (the default, or "
        "with --dot) or draw it as a PNG picture with --png (no Graphviz needed): one box per "
        "component with its id, type and ports, one arrow per connection, dashed when delayed.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_graph_args(p)
    p.add_argument("--dot", action="store_true", help="print DOT text on stdout (the default without --png)")
    p.add_argument("--png", metavar="FILE", help="draw the graph into this PNG file")
    p.add_argument("--dpi", type=int, default=150, help="resolution of the PNG (default: 150)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    session = open_session()
    spec = load_spec(session, args)
    if not MIN_DPI <= args.dpi <= MAX_DPI:  # 10^5 dpi would allocate gigabytes for the picture
        raise CommandError(f"--dpi {args.dpi}: expected {MIN_DPI} to {MAX_DPI}", EXIT_USAGE)
    if args.png:
        out = Path(args.png)
        if not out.parent.is_dir():
            raise CommandError(f"--png {args.png}: no directory '{out.parent}'", EXIT_FAILED)
        check_writable_file(args.png, "--png")
        check_output_over_inputs(args.png, "--png", spec, session)
        try:  # the engine's one optional library: the picture only
            import matplotlib  # noqa: F401
        except ModuleNotFoundError:
            raise CommandError("--png draws with matplotlib, which is not installed: "
                               "pip install 'impala-flow[plot]'", EXIT_FAILED) from None
    net = session.build(spec)
    if args.png:
        draw_png(net, out, dpi=args.dpi)
        print(f"{out}: {len(net.components)} components, {len(net.connections)} connections", file=sys.stderr)
    if args.dot or not args.png:
        sys.stdout.write(to_dot(net))
    return 0


# --- layout -----------------------------------------------------------------------------------
ROW = 0.2          # inches per port row
HEAD = 0.5         # header: id and type
PAD = 0.14         # inner horizontal padding
COL_GAP = 1.15     # between columns
BOX_GAP = 0.45     # between boxes of a column
CHAR = 0.6 / 72    # average character width per point of font size (inches)


def _text_w(text: str, size: float, bold: bool = False) -> float:
    return len(text) * size * CHAR * (1.1 if bold else 1.0)


@dataclass
class Box:
    name: str
    kind: str
    ins: list[str]
    outs: list[str]
    role: str  # source | sink | component
    layer: int = 0
    x: float = 0.0  # left
    y: float = 0.0  # top (y grows downward)
    w: float = 0.0
    h: float = 0.0
    order: float = 0.0

    def in_xy(self, port: str) -> tuple[float, float]:
        return self.x, self.y + HEAD + ROW * (self.ins.index(port) + 0.5)

    def out_xy(self, port: str) -> tuple[float, float]:
        return self.x + self.w, self.y + HEAD + ROW * (self.outs.index(port) + 0.5)


def layout(net: Network) -> dict[str, Box]:
    """Boxes placed left to right by topological generation, ordered to keep arrows short."""
    boxes: dict[str, Box] = {}
    for c in net.order():
        role = "source" if isinstance(c, Source) else ("sink" if not c.outputs else "component")
        b = Box(c.name, type(c).type_name or type(c).__name__, list(c.inputs), list(c.outputs), role)
        in_w = max((_text_w(p, 7.5) for p in b.ins), default=0.0)
        out_w = max((_text_w(p, 7.5) for p in b.outs), default=0.0)
        b.w = max(1.3, _text_w(b.name, 10, bold=True) + 2 * PAD, _text_w(b.kind, 8) + 2 * PAD,
                  in_w + out_w + 3 * PAD)
        b.h = HEAD + ROW * max(len(b.ins), len(b.outs)) + (0.1 if (b.ins or b.outs) else 0.0)
        boxes[c.name] = b
    import networkx as nx  # here, not at import: every command (run too) imports this module

    g = net.digraph(include_delayed=False)
    layers: list[list[str]] = []
    rank = {n: k for k, n in enumerate(boxes)}
    for i, gen in enumerate(nx.topological_generations(g)):
        layers.append(sorted(gen, key=rank.__getitem__))
        for n in gen:
            boxes[n].layer = i
    # order inside each column: barycentre of the neighbours in the other columns, sweeping
    # right then left, twice
    for names in layers:
        for j, n in enumerate(names):
            boxes[n].order = j
    und = g.to_undirected()
    for _sweep in range(2):
        for names in layers[1:] + layers[-2::-1]:
            bary = {}
            for n in names:
                nb = [boxes[m].order for m in und.neighbors(n) if boxes[m].layer != boxes[n].layer]
                bary[n] = sum(nb) / len(nb) if nb else boxes[n].order
            names.sort(key=bary.__getitem__)
            for j, n in enumerate(names):
                boxes[n].order = j
    # x: columns as wide as their widest box
    x = 0.0
    for names in layers:
        width = max(boxes[n].w for n in names)
        for n in names:
            boxes[n].x = x + (width - boxes[n].w) / 2
        x += width + COL_GAP
    # y: first column stacked; later columns aim at their inputs' ports, then packed
    for k, names in enumerate(layers):
        want: dict[str, float] = {}
        for n in names:
            b = boxes[n]
            ys = []
            for conn in net.connections:
                if conn.dst.owner.name == n and not conn.delayed and boxes[conn.src.owner.name].layer < k:
                    src = boxes[conn.src.owner.name]
                    ys.append(src.out_xy(conn.src.name)[1] - (b.in_xy(conn.dst.name)[1] - b.y))
            want[n] = sum(ys) / len(ys) if ys and k else float("nan")
        _pack(names, boxes, want)
    top = min(b.y for b in boxes.values())
    for b in boxes.values():
        b.y -= top
    return boxes


def _pack(names: list[str], boxes: dict[str, Box], want: dict[str, float]) -> None:
    """Place a column's boxes in order, each near its wanted top, never overlapping."""
    known = [want[n] for n in names if want[n] == want[n]]
    base = sum(known) / len(known) if known else 0.0
    y = None
    desired = []
    for n in names:
        w = want[n] if want[n] == want[n] else base
        top = w if y is None else max(w, y)
        boxes[n].y = top
        desired.append(w)
        y = top + boxes[n].h + BOX_GAP
    # shift the column so it sits, on average, where its boxes want to be
    shift = sum(d - boxes[n].y for d, n in zip(desired, names, strict=True)) / len(names)
    for n in names:
        boxes[n].y += shift


# --- drawing ----------------------------------------------------------------------------------
FILL = {"source": "#e4f3e0", "component": "#e8eff9", "sink": "#fbeedd"}
EDGE = {"source": "#5a8f4e", "component": "#4f6f9f", "sink": "#b07a3a"}


def _route(x0: float, y0: float, x1: float, y1: float, boxes: dict[str, Box], skip: set[str],
           used: dict[tuple[float, int], int]) -> tuple[list, list]:
    """Bezier path (Path vertices and codes) from an output to an input port, around boxes.

    An arrow that crosses a column passes through the gap between two of its boxes (or
    above or below them) nearest its way; arrows sharing a gap get parallel lanes (``used``).
    """
    from matplotlib.path import Path as MPath

    verts: list[tuple[float, float]] = [(x0, y0)]
    codes = [MPath.MOVETO]
    # columns crossed on the way: pass each through a free gap near the straight line
    blockers = sorted((b for b in boxes.values() if b.name not in skip and b.x > x0 + 1e-6 and b.x + b.w < x1 - 1e-6),
                      key=lambda b: b.x)
    cols: dict[float, list[Box]] = {}
    for b in blockers:
        cols.setdefault(round(b.x + b.w / 2, 3), []).append(b)
    pts = [(x0, y0)]
    for cx in sorted(cols):
        col = sorted(cols[cx], key=lambda b: b.y)
        left = min(b.x for b in col) - 0.15
        right = max(b.x + b.w for b in col) + 0.15
        t = (cx - x0) / (x1 - x0)
        yline = y0 + t * (y1 - y0)
        if not any(b.y - 0.05 <= yline <= b.y + b.h + 0.05 for b in col):
            continue
        gaps = [col[0].y - BOX_GAP / 2] + [(a.y + a.h + b.y) / 2 for a, b in zip(col, col[1:], strict=False)]
        gaps.append(col[-1].y + col[-1].h + BOX_GAP / 2)
        prev = pts[-1][1]
        i = min(range(len(gaps)), key=lambda j: abs(gaps[j] - yline) + 0.5 * abs(gaps[j] - prev))
        n = used.get((cx, i), 0)
        used[(cx, i)] = n + 1
        yg = gaps[i] + (n + 1) // 2 * 0.1 * (1 if n % 2 else -1)
        pts += [(left, yg), (right, yg)]
    pts.append((x1, y1))
    for (ax, ay), (bx, by) in zip(pts, pts[1:], strict=False):
        k = max(0.25, (bx - ax) * 0.5)
        verts += [(ax + k, ay), (bx - k, by), (bx, by)]
        codes += [MPath.CURVE4] * 3
    return verts, codes


def _rounded(points: list[tuple[float, float]], r: float) -> tuple[list, list]:
    """A polyline with rounded corners, as Path vertices and codes."""
    from matplotlib.path import Path as MPath

    verts, codes = [points[0]], [MPath.MOVETO]
    for (ax, ay), (bx, by), (cx, cy) in zip(points, points[1:], points[2:], strict=False):
        d1 = max(abs(bx - ax) + abs(by - ay), 1e-9)
        d2 = max(abs(cx - bx) + abs(cy - by), 1e-9)
        k1, k2 = min(r, d1 / 2) / d1, min(r, d2 / 2) / d2
        verts += [(bx - (bx - ax) * k1, by - (by - ay) * k1), (bx, by), (bx + (cx - bx) * k2, by + (cy - by) * k2)]
        codes += [MPath.LINETO, MPath.CURVE3, MPath.CURVE3]
    verts.append(points[-1])
    codes.append(MPath.LINETO)
    return verts, codes


def draw_png(net: Network, path: str | Path, dpi: int = 150) -> None:
    """Draw ``net`` into a PNG file with matplotlib (Agg backend; no Graphviz needed)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, FancyArrowPatch, FancyBboxPatch
    from matplotlib.path import Path as MPath

    boxes = layout(net)
    if not boxes:
        raise CommandError("the graph has no component to draw", EXIT_FAILED)
    right = max(b.x + b.w for b in boxes.values())
    bottom = max(b.y + b.h for b in boxes.values())
    delayed = [c for c in net.connections if c.delayed]
    lane0 = bottom + 0.35
    bottom_all = lane0 + 0.22 * len(delayed) + 0.1 if delayed else bottom
    margin, title_h = 0.35, 0.55
    fig_w, fig_h = right + 2 * margin, bottom_all + 2 * margin + title_h
    fig = Figure(figsize=(fig_w, fig_h), dpi=dpi)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(-margin, right + margin)
    ax.set_ylim(bottom_all + margin, -margin - title_h)  # y grows downward
    ax.set_axis_off()
    ax.set_aspect("equal")
    ax.text(-margin + 0.15, -margin - title_h + 0.12, net.name, fontsize=13, fontweight="bold", va="top")
    n_delay = f", {len(delayed)} delayed (dashed)" if delayed else ""
    ax.text(-margin + 0.15, -margin - title_h + 0.38, f"{len(boxes)} components, {len(net.connections)} "
            f"connections{n_delay}; left to right in graph order", fontsize=8, color="#666666", va="top")
    palette = matplotlib.colormaps["tab10"].colors
    colour = {n: palette[i % len(palette)] for i, n in enumerate(boxes)}
    for b in boxes.values():
        ax.add_patch(FancyBboxPatch((b.x, b.y), b.w, b.h, boxstyle="round,pad=0,rounding_size=0.08",
                                    facecolor=FILL[b.role], edgecolor=EDGE[b.role], linewidth=1.2, zorder=2))
        ax.text(b.x + b.w / 2, b.y + 0.17, b.name, ha="center", va="center", fontsize=10, fontweight="bold",
                zorder=3)
        ax.text(b.x + b.w / 2, b.y + 0.36, b.kind, ha="center", va="center", fontsize=8, color="#555555",
                style="italic", zorder=3)
        if b.ins or b.outs:
            ax.plot([b.x + 0.06, b.x + b.w - 0.06], [b.y + HEAD - 0.02] * 2, color=EDGE[b.role],
                    linewidth=0.5, alpha=0.6, zorder=3)
        for p in b.ins:
            px, py = b.in_xy(p)
            ax.add_patch(Circle((px, py), 0.035, color=EDGE[b.role], zorder=4))
            ax.text(px + PAD * 0.8, py, p, ha="left", va="center", fontsize=7.5, zorder=3)
        for p in b.outs:
            px, py = b.out_xy(p)
            ax.add_patch(Circle((px, py), 0.035, color=colour[b.name], zorder=4))
            ax.text(px - PAD * 0.8, py, p, ha="right", va="center", fontsize=7.5, zorder=3)
    lane = lane0
    used: dict[tuple[float, int], int] = {}
    for c in net.connections:
        src, dst = boxes[c.src.owner.name], boxes[c.dst.owner.name]
        (x0, y0), (x1, y1) = src.out_xy(c.src.name), dst.in_xy(c.dst.name)
        col = colour[src.name]
        if c.delayed or x1 <= x0:
            verts, codes = _rounded([(x0, y0), (x0 + 0.3, y0), (x0 + 0.3, lane), (x1 - 0.3, lane),
                                     (x1 - 0.3, y1), (x1, y1)], 0.12)
            ax.text((x0 + x1) / 2, lane + 0.02, f"{src.name}.{c.src.name} → {dst.name}.{c.dst.name}  [delay]",
                    ha="center", va="top", fontsize=7, color=col,
                    bbox={"boxstyle": "round,pad=0.15", "facecolor": "white", "edgecolor": "none"}, zorder=5)
            lane += 0.22
            style = "--"
        else:
            verts, codes = _route(x0, y0, x1, y1, boxes, {src.name, dst.name}, used)
            style = "-"
        ax.add_patch(FancyArrowPatch(path=MPath(verts, codes), arrowstyle="-|>,head_length=5,head_width=2.5",
                                     color=col, linewidth=1.3, linestyle=style, alpha=0.9, zorder=1,
                                     shrinkA=0, shrinkB=3))
    fig.savefig(str(path), dpi=dpi, facecolor="white")
