"""What a benchmark's report says besides its figures: the code it measured (others may commit, or change files,
while a run goes on), and its own section of bench/README.template.md and bench/README.md, between its two
markers, which the bad-link bench (badlink.py) and the rover bench (nav_bench.py) rewrite after a full run (the suite,
suite.py, writes the rest of README.md from the template)."""

import hashlib
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parent
REPO = BENCH.parent


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
