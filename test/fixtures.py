"""Fixture factories shared by the integration test modules."""

import pytest

from harness import start_bridge


def bridge_fixture(node_name, **settings):
    """A module's `bridge` fixture: a bridge node with these settings (its port), stopped after the module."""

    @pytest.fixture(scope="module")
    def bridge(ros):
        proc, port = start_bridge(ros, node_name=node_name, **settings)
        yield port
        proc.stop()

    return bridge
