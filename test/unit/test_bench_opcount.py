"""The bench's opcode counter (bench/opcount/sitecustomize.py): it counts in the script it is told of, and only
there, and its count grows with the work done, by the same amount for the same work."""

import os
import subprocess
import sys
from pathlib import Path

OPCOUNT = Path(__file__).resolve().parents[2] / "bench" / "opcount"
WORK = """
import os, signal, sys
for _ in range(int(sys.argv[1])):
    pass
if signal.getsignal(signal.SIGUSR2) is not signal.SIG_DFL:  # (the counter's: it writes the count)
    os.kill(os.getpid(), signal.SIGUSR2)
"""


def run(tmp_path, loops, counted="work.py"):
    script, out = tmp_path / "work.py", tmp_path / f"count-{loops}"
    script.write_text(WORK)
    env = {**os.environ, "PYTHONPATH": str(OPCOUNT), "BENCH_OPCODES": str(out), "BENCH_OPCODES_OF": counted}
    subprocess.run([sys.executable, str(script), str(loops)], env=env, check=True, timeout=30)
    return int(out.read_text()) if out.exists() else None


def test_the_count_grows_by_the_same_amount_for_the_same_work(tmp_path):
    counts = [run(tmp_path, loops) for loops in (1000, 2000, 3000)]
    assert counts[0] > 0
    assert counts[1] - counts[0] == counts[2] - counts[1] >= 1000


def test_another_script_is_not_counted(tmp_path):
    assert run(tmp_path, 10, counted="rosbridge_websocket") is None
