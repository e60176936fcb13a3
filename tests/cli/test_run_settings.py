"""`rcmlconf run` turns click's options into one `RunSettings`.

Each option has a field. The target options go to `TargetSettings`, which other commands can
share.
"""

from __future__ import annotations

from typing import Any

import pytest

from rcmlconf.cli.run import run, run_settings
from rcmlconf.conformance.run_defaults import CONNECT_TIMEOUT, SESSION_WAIT


def parsed(*args: str) -> dict[str, Any]:
    """The options as click gives them to `run`, for these arguments."""
    return dict(run.make_context("run", list(args)).params)


def test_the_defaults_are_the_options_defaults() -> None:
    settings = run_settings(parsed())
    tested = settings.tested
    files = (tested.rcml, tested.model, tested.ics)
    assert (tested.target, tested.rsp_target, tested.listen, tested.site) == (None,) * 4
    assert (*files, tested.client_command) == (None,) * 4
    assert (tested.role, tested.connect_timeout, tested.faults) == ("server", CONNECT_TIMEOUT, ())
    assert (settings.repeat, settings.timeout_scale, settings.seed) == (1, 1.0, 0)
    assert (settings.session_wait, settings.concurrency) == (SESSION_WAIT, 16)
    assert (settings.list_only, settings.strict, settings.verbose) == (False,) * 3


def test_each_option_lands_in_its_field() -> None:
    settings = run_settings(
        parsed(
            "--rsp-target=10.0.0.7",
            "--role=local",
            "--listen=7340",
            "--only=rsp/*",
            "--json=run.json",
            "--fault=bare-lf",
            "--impair=loss=5%",
        )
    )
    assert settings.tested.rsp_target == ("10.0.0.7", 7340)
    assert settings.tested.listen == ("127.0.0.1", 7340)
    assert settings.tested.role == "local"
    assert settings.tested.faults == ("bare-lf",)
    assert settings.only == ("rsp/*",)
    assert str(settings.reports.json) == "run.json"
    assert settings.reports.junit is None
    assert settings.impair == "loss=5%"


def test_an_option_without_a_field_is_a_bug_said_at_once() -> None:
    options = parsed()
    options["unheard"] = 1
    with pytest.raises(TypeError, match="unheard"):
        run_settings(options)
