"""Shell completion, as README's "Reports and CI" tells a user to turn it on: click's, through
the `_RCMLCONF_COMPLETE` variable of the installed command."""

from __future__ import annotations

import os
import subprocess

from support.processes import BOUND, COMMAND


def complete(*env: tuple[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        COMMAND,
        env={**os.environ, **dict(env)},
        capture_output=True,
        text=True,
        timeout=BOUND,
        check=False,
    )


def test_bash_gets_a_script_and_completes_commands_and_options() -> None:
    script = complete(("_RCMLCONF_COMPLETE", "bash_source"))
    assert script.returncode == 0
    assert "complete " in script.stdout
    assert "_rcmlconf_completion" in script.stdout
    words = ("COMP_WORDS", "rcmlconf va"), ("COMP_CWORD", "1")
    done = complete(("_RCMLCONF_COMPLETE", "bash_complete"), *words)
    assert done.stdout.splitlines() == ["plain,validate"]
    words = ("COMP_WORDS", "rcmlconf validate --for"), ("COMP_CWORD", "2")
    done = complete(("_RCMLCONF_COMPLETE", "bash_complete"), *words)
    assert "plain,--format" in done.stdout.splitlines()
