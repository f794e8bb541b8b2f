"""ARCHITECTURE.md's message routes name real code: every hop `file.Class.method` (a path under src/rosbridge,
then names) is defined there (read with ast, nothing imported)."""

import ast
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
ROOT = REPO / "src" / "rosbridge"
HOP = re.compile(r"`([a-z_]+(?:/[a-z_0-9]+)*)\.([A-Za-z_][\w.]*)`")


def routes_text():
    text = (REPO / "ARCHITECTURE.md").read_text()
    return text[text.index("## A message's route") : text.index("## Threads")]


def defined(path, dotted):
    """Whether `dotted` (Name, Class.method, ...) is defined at the top of the module at `path`."""
    body = ast.parse(path.read_text()).body
    for name in dotted.split("."):
        found = None
        for node in body:
            if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.name == name:
                found = node
            elif isinstance(node, ast.Assign) and any(getattr(t, "id", None) == name for t in node.targets):
                found = node
            elif isinstance(node, ast.AnnAssign) and getattr(node.target, "id", None) == name:
                found = node
        if found is None:
            return False
        body = getattr(found, "body", [])
    return True


def test_every_hop_of_the_routes_is_in_the_code():
    hops = HOP.findall(routes_text())
    assert len(hops) > 30
    missing = [f"{module}.{name}" for module, name in hops if not defined(ROOT / f"{module}.py", name)]
    assert not missing, missing


def test_a_hop_that_is_not_in_the_code_is_found(tmp_path):
    module = tmp_path / "m.py"
    module.write_text("class A:\n    def b(self):\n        pass\n")
    assert defined(module, "A.b") and not defined(module, "A.c") and not defined(module, "B")
