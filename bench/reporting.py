"""The benchmarks' reports: their figures as text (fmt), their markdown tables (Table, markdown), the code they
measured (others may commit, or change files, while a run goes on), and a bench's own section of
bench/README.template.md and bench/README.md, between its two markers, which the bad-link bench (badlink.py) and the
rover bench (nav_bench.py) rewrite after a full run (the suite, suite.py, writes the rest of README.md from the
template)."""

import hashlib
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parent
REPO = BENCH.parent


def fmt(value, unit=""):
    """A figure and its unit, as every table writes it: three significant digits (whole numbers from 100 on); "n/a"
    if it was not measured, "none" (NaN) if it was and never came. Two units take values in another unit: "%" a
    fraction (one decimal, two where one would round a loss away), "s" seconds (shown in ms below a second)."""
    if value is None:
        return "n/a"
    if value != value:
        return "none"
    if unit == "%":
        return f"{value * 100:.1f}%" if value >= 1 or value < 0.9995 else f"{value * 100:.2f}%"
    if unit == "x":
        return f"{value:.2f}x"
    if unit == "s" and abs(value) < 1:
        value, unit = value * 1e3, "ms"
    number = f"{value:,.0f}" if abs(value) >= 100 else f"{value:.3g}"
    return f"{number}{unit}" if unit.startswith("/") else f"{number} {unit}".strip()


def markdown_row(cells):
    return "| " + " | ".join(cells) + " |"


def markdown(head, align, rows):
    """A markdown table: its head's cells, each column's alignment ("---" or "---:") and its rows' cells."""
    return "\n".join([markdown_row(head), "|" + "|".join(align) + "|", *map(markdown_row, rows)])


class Table:
    """The benches' table of figures: Figure | Bridge | Baseline (same run) | Ratio | Target | met; the ratio of
    the bridge's value to the baseline's is computed. `extra` ({key: title}) adds a last column for each other server
    measured in the same run (e.g. the bridge of an earlier commit, rosbridge_server 0.11.17); `notes` go below."""

    def __init__(self, extra=None):
        self.rows, self.notes, self.extra = [], [], dict(extra or {})

    def row(self, figure, value, unit, baseline_name, baseline, target="", ok=None, others=None):
        ratio = value / baseline if value is not None and baseline else None
        self.text_row(
            figure,
            fmt(value, unit),
            f"{baseline_name}: {fmt(baseline, unit)}" if baseline_name else "",
            {k: fmt(v, unit) for k, v in (others or {}).items() if v is not None},
            fmt(ratio, "x") if ratio is not None else "",
            target,
            "" if ok is None else ("met" if ok else "**missed**"),
        )

    def text_row(self, figure, value, baseline, others=None, ratio="", target="", met=""):
        """A row of texts: e.g. a figure at the start and at the end of the window (no ratio, no goal)."""
        others = others or {}
        self.rows.append([figure, value, baseline, ratio, target, met] + [others.get(key, "") for key in self.extra])

    def markdown(self):
        head = ["Figure", "Bridge", "Baseline (same run)", "Ratio", "Target", ""]
        head += [f"{title} (same run)" for title in self.extra.values()]
        align = ["---", "---:", "---", "---:", "---", "---"] + ["---:"] * len(self.extra)
        return markdown(head, align, self.rows)


def write_section(markers, text):
    for name in ("README.template.md", "README.md"):
        path = BENCH / name
        old = path.read_text()
        if markers[0] not in old:
            raise SystemExit(f"{path} has no {markers[0]} ... {markers[1]} section")
        head, rest = old.split(markers[0], 1)
        tail = rest.split(markers[1], 1)[1]
        path.write_text(f"{head}{markers[0]}\n{text}\n{markers[1]}{tail}")
        print(f"wrote {path}", file=sys.stderr)


def _uncommitted():
    """A digest of the uncommitted changes to src/ and web/ (tracked and new files), and whether there are any."""
    diff = subprocess.run(["git", "-C", str(REPO), "diff", "HEAD", "--", "src", "web"], capture_output=True)
    untracked = subprocess.run(
        ["git", "-C", str(REPO), "ls-files", "--others", "--exclude-standard", "src", "web"],
        capture_output=True,
        text=True,
    ).stdout.split()
    digest = hashlib.sha1(diff.stdout)
    for name in sorted(untracked):
        digest.update((REPO / name).read_bytes() if (REPO / name).is_file() else b"")
    return digest.hexdigest(), bool(diff.stdout or untracked)


def code_state():
    """The bridge's and the page's code as a case found it: HEAD, and a digest of any uncommitted change to src/
    or web/ (others may commit while a run goes on)."""
    head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    digest, changed = _uncommitted()
    return head.stdout.strip() + (f"+{digest[:6]}" if changed else "")


def git_head():
    """The commit measured, and whether the bridge's or the page's files differed from it (others' work)."""
    head = subprocess.run(["git", "-C", str(REPO), "log", "-1", "--format=%h %s"], capture_output=True, text=True)
    if head.returncode:
        return "an unknown commit"
    dirty = subprocess.run(
        ["git", "-C", str(REPO), "status", "--porcelain", "--", "src", "web"], capture_output=True, text=True
    ).stdout.split("\n")
    dirty = [line[3:] for line in dirty if line.strip()]
    return f"commit `{head.stdout.strip()[:70]}`" + (
        f" with uncommitted changes in {', '.join(dirty[:8])}{' ...' if len(dirty) > 8 else ''}" if dirty else ""
    )


def code_digest():
    """A digest of the bridge's and the page's code as it is now (src/ and web/, committed and not): what a run
    compares at its start and end (a commit elsewhere in the repository leaves it alone)."""
    trees = subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD:src", "HEAD:web"], capture_output=True)
    return hashlib.sha1(trees.stdout + _uncommitted()[0].encode()).hexdigest()[:8]
