"""transport/connection.ClientConnection's reading states are its Waiting enum's: every value given to or compared
with `_waiting` is a member of Waiting (or None), never a string (read with ast, nothing imported)."""

import ast
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[2] / "src" / "rosbridge" / "transport" / "connection.py"


def is_state(value):
    """Waiting.<member>, or None."""
    named = isinstance(value, ast.Attribute) and isinstance(value.value, ast.Name) and value.value.id == "Waiting"
    return named or (isinstance(value, ast.Constant) and value.value is None)


def states_used(tree):
    """Each value (an ast node) given to or compared with `_waiting`."""
    used = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign):
            targets = [t for target in node.targets for t in getattr(target, "elts", [target])]
            values = getattr(node.value, "elts", [node.value])
            used += [value for target, value in zip(targets, values) if getattr(target, "attr", None) == "_waiting"]
        elif isinstance(node, ast.Compare) and getattr(node.left, "attr", None) == "_waiting":
            used += [v for comparator in node.comparators for v in getattr(comparator, "elts", [comparator])]
    return used


def strays(used):
    return [(value.lineno, ast.unparse(value)) for value in used if not is_state(value)]


def test_every_reading_state_is_a_waiting_member():
    tree = ast.parse(SOURCE.read_text())
    [enum] = [node for node in tree.body if isinstance(node, ast.ClassDef) and node.name == "Waiting"]
    defined = {target.id for node in enum.body if isinstance(node, ast.Assign) for target in node.targets}
    used = states_used(tree)
    assert strays(used) == []
    assert {value.attr for value in used if isinstance(value, ast.Attribute)} == defined
    assert defined == {"READ", "TURN", "SESSION", "END"}


def test_a_string_state_is_found():
    used = states_used(ast.parse('self._waiting = "read"\nif self._waiting in ("end", None): pass\n'))
    assert strays(used) == [(1, "'read'"), (2, "'end'")]
