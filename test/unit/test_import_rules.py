"""ARCHITECTURE.md's rules of who may import whom in src/rosbridge, checked against every import statement (read
with ast, nothing imported): a protocol never imports the transport, the pure parts never import tornado or
rospy, nothing imports the node."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2] / "src" / "rosbridge"
PARTS = ("protocol", "foxglove", "transport", "http", "ros_side", "codec")
SHARED = (
    "settings",
    "errors",
    "globs",
    "auth",
    "origins",
    "off_loop",
    "borrowed",
    "accepting",
    "heap",
    "message_types",
)
# part -> (rosbridge modules it may import: a part, or part.module; libraries it never imports)
RULES = {
    "codec": ({"codec", "message_types", "errors"}, {"tornado", "rospy"}),
    "protocol": ({"protocol", "codec", "contract", *SHARED}, {"tornado", "rospy"}),
    # the second protocol: the outbox and the frames are rosbridge's, shared; nothing else of it
    "foxglove": (
        {"foxglove", "protocol.outbox", "protocol.encoded", "codec", "contract", *SHARED},
        {"tornado", "rospy"},
    ),
    "transport": ({"transport", "protocol", "foxglove", "codec", *SHARED}, {"rospy"}),
    "http": ({"http", "transport.unsent", "protocol", "codec", "contract", *SHARED}, {"rospy"}),
    "ros_side": ({"ros_side", "codec", "contract", "protocol.encoded", *SHARED}, set()),
    "shared": (set(SHARED), set()),
    "contract": ({"errors", "globs"}, {"tornado", "rospy"}),
}


def part_of(path):
    relative = path.relative_to(ROOT).with_suffix("")
    head = relative.parts[0]
    if head in PARTS:
        return head
    if head in SHARED:
        return "shared"
    return head  # contract, server, __init__


def imports(path):
    """(module, line) for every `import x` and `from x import y` (y too, when it may be a module of x)."""
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            yield node.module, node.lineno
            for alias in node.names:
                yield f"{node.module}.{alias.name}", node.lineno


def allowed(target, permitted):
    """Whether rosbridge.<target> (dotted) falls under one of `permitted` (a part, or part.module)."""
    return any(target == name or target.startswith(name + ".") for name in permitted)


def is_module(dotted):
    path = ROOT.joinpath(*dotted.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


SOURCES = sorted(ROOT.rglob("*.py"))


def test_every_file_belongs_to_a_part_the_rules_know():
    assert {part_of(path) for path in SOURCES} <= {*RULES, "server", "__init__"}


@pytest.mark.parametrize("path", SOURCES, ids=lambda path: str(path.relative_to(ROOT)))
def test_imports_follow_the_rules(path):
    part = part_of(path)
    broken = []
    for module, line in imports(path):
        top, _, rest = module.partition(".")
        if part in RULES and top in RULES[part][1]:
            broken.append(f"line {line}: {module} (a {part} module never imports {top})")
        if top != "rosbridge" or not rest or not is_module(rest):
            continue
        if rest == "server" or rest.startswith("server."):
            broken.append(f"line {line}: {module} (nothing imports the node)")
        elif part in RULES and not allowed(rest, RULES[part][0] | {part}):
            broken.append(f"line {line}: {module} (not among what {part} may import)")
    assert not broken, f"{path.relative_to(ROOT)}:\n" + "\n".join(broken)


def test_the_rules_catch_a_protocol_importing_the_transport(tmp_path):
    """The check itself: a protocol module that imported the transport or tornado would fail."""
    module = tmp_path / "bad.py"
    module.write_text("import tornado.web\nfrom rosbridge.transport import rfc6455\n")
    found = [name for name, _ in imports(module)]
    assert "tornado.web" in found and "rosbridge.transport.rfc6455" in found
    assert not allowed("transport.rfc6455", RULES["protocol"][0])
