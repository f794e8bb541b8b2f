import pytest

from rosbridge.globs import Globs, allowed, filter_names, parse_globs


@pytest.mark.parametrize(
    "text, expected",
    [
        ("[/turtle1/*, /rosout]", ["/turtle1/*", "/rosout"]),
        ("['*']", ["*"]),
        ("['/a/*', '/b']", ["/a/*", "/b"]),
        ('["/a/*", "/b"]', ["/a/*", "/b"]),
        ("/turtle1/*", ["/turtle1/*"]),
        ("  [ /a ,, /b , ]  ", ["/a", "/b"]),
        (["/a/*", "/b"], ["/a/*", "/b"]),
    ],
)
def test_parse_globs_reads_the_launch_arg_format(text, expected):
    assert parse_globs(text) == expected


@pytest.mark.parametrize("text", [None, "", "   ", "[]", "[ ]", "['']", "[,]", []])
def test_empty_glob_list_means_no_filter(text):
    assert parse_globs(text) is None


def test_parse_globs_rejects_non_string():
    with pytest.raises(ValueError, match="glob list"):
        parse_globs(42)


def test_allowed_uses_fnmatch_patterns():
    patterns = parse_globs("[/turtle1/*, /rosout]")
    assert allowed("/turtle1/cmd_vel", patterns)
    assert allowed("/turtle1/pose", patterns)
    assert allowed("/rosout", patterns)
    assert not allowed("/rosout_agg", patterns)
    assert not allowed("/turtle2/cmd_vel", patterns)
    assert not allowed("/Turtle1/pose", patterns)  # case-sensitive like ROS names


def test_none_allows_everything_and_a_non_matching_pattern_hides_everything():
    assert allowed("/anything/at/all", None)
    assert not allowed("/anything", parse_globs("[none]"))


def test_filter_names_keeps_order():
    assert filter_names(["/b/x", "/a", "/b/y", "/c"], ["/b/*", "/a"]) == ["/b/x", "/a", "/b/y"]
    assert filter_names(["/b", "/a"], None) == ["/b", "/a"]


def test_globs_parse_reads_the_three_launch_args():
    globs = Globs.parse(topics_glob="[/turtle1/*]", services_glob="", params_glob="['/a', '/b/*']")
    assert globs.topics == ["/turtle1/*"]
    assert globs.services is None
    assert globs.params == ["/a", "/b/*"]
    assert Globs().topics is None and Globs().services is None and Globs().params is None
