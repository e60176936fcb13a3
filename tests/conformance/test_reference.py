"""The suite proves itself on the embedded reference: every case passes, run after run, and the
registry keeps its promises (stable IDs, known requirements, every MUST covered)."""

from __future__ import annotations

import asyncio

from rcmlconf.conformance.coverage import matrix, unknown_requirements
from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.registry import Role, all_cases
from rcmlconf.conformance.runner import RunOptions, run_cases
from rcmlconf.conformance.targets import embedded_reference
from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.specs import requirements

#: The documents whose every MUST needs a case (issue "The conformance harness").
RUNTIME_DOCUMENTS = ("rctp-2.0.md", "rsp.md")
#: Cases the reference cannot make applicable, and why.
NOT_APPLICABLE = {
    # Its robots offer every AEAD of D-RSP-21: there is none to refuse.
    "rsp/session/encryption-not-offered",
    # CUBO's speaker has no monitor (D-RSP-23): what it plays cannot be seen.
    "rsp/audio/in-order",
    "rsp/audio/late-dropped",
}


def run_all(options: RunOptions) -> list[Result]:
    async def main() -> list[Result]:
        async with embedded_reference(EVERYTHING.features) as target:
            cases = [c for c in all_cases().values() if c.role is not Role.CLIENT]
            return await run_cases(cases, target, options)

    return asyncio.run(asyncio.wait_for(main(), 120))


def test_every_case_passes_on_the_reference_twice_with_the_same_verdicts() -> None:
    results = run_all(RunOptions(repeat=2))
    cases = all_cases()
    failing = [
        f"{r.case} (run {r.run}): {r.verdict.value}: {r.reason}\n" + "\n".join(r.exchange)
        for r in results
        if r.verdict is not Verdict.PASS
        and not (r.verdict is Verdict.NOT_APPLICABLE and r.case in NOT_APPLICABLE)
        # A case run under its own impairment may find the answer hidden by it: inconclusive,
        # never a failure (rsp/reliable/memory-commands-under-loss, a few runs in a thousand).
        and not (r.verdict is Verdict.INCONCLUSIVE and cases[r.case].impairment is not None)
    ]
    assert not failing, "\n\n".join(failing)


def test_every_case_names_requirements_of_specs_and_every_must_has_a_case() -> None:
    cases = all_cases()
    texts = requirements()
    assert unknown_requirements(cases.values(), texts) == {}
    uncovered = [
        row.requirement.id
        for row in matrix(cases.values(), texts)
        if row.requirement.document in RUNTIME_DOCUMENTS
        and row.requirement.mandatory
        and not row.covered
    ]
    assert uncovered == []


def test_case_purposes_are_one_line_and_timeouts_bounded() -> None:
    for case in all_cases().values():
        assert "\n" not in case.purpose, case.id
        assert 0 < case.timeout <= 30, case.id
