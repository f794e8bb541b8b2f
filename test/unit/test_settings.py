"""The bridge's settings table is the one source: the launch file, the README and the node's parsing agree."""

import xml.etree.ElementTree as ElementTree

import pytest

from rosbridge import settings

from harness import REPO


def test_the_readme_table_is_the_settings_table():
    assert settings.markdown_table() in (REPO / "README.md").read_text()


def test_the_launch_file_passes_every_setting_with_its_default():
    launch = ElementTree.parse(REPO / "launch" / "rosbridge_websocket.launch").getroot()
    args = {arg.get("name"): arg.get("default") for arg in launch.iter("arg")}
    params = {param.get("name"): param.get("value") for param in launch.find("node").iter("param")}
    assert set(params) == {s.name for s in settings.SETTINGS}
    for setting in settings.SETTINGS:
        assert params[setting.name] == f"$(arg {setting.name})"
        assert settings.convert(setting, args[setting.name]) == setting.default, setting.name


def test_values_from_launch_text_are_typed_and_bad_ones_named():
    values = {"port": "0", "ssl": "true", "fragment_timeout": "2.5", "topics_glob": "[/a]"}
    current = settings.Settings(values.get)
    assert (current.port, current.ssl, current.fragment_timeout, current.topics_glob) == (0, True, 2.5, "[/a]")
    assert current.max_queue == 1000
    with pytest.raises(settings.SettingError, match="setting max_queue: expected int, got 'many'"):
        settings.Settings({"max_queue": "many"}.get)
    with pytest.raises(settings.SettingError, match="setting ssl: expected bool"):
        settings.Settings({"ssl": "yes please"}.get)


@pytest.mark.parametrize("name", [s.name for s in settings.SETTINGS if s.kind is float and s.check is not None])
@pytest.mark.parametrize("value", ["inf", "-inf", "nan", float("inf")])
def test_a_float_setting_with_a_check_refuses_what_is_not_finite(name, value):
    with pytest.raises(settings.SettingError, match=f"setting {name}: must be a finite number, got"):
        settings.Settings({name: value}.get)
