"""The conformance harness (`rcmlconf run`): cases that each check requirements of specs/ against
an implementation under test, their verdicts, and the reports of a run.

- `verdicts`: the five verdicts and how a case reaches one;
- `registry`: the cases, by stable ID, with their requirements, role, timeout and impairment;
- `probes`: what a case talks to a target with (an RCTP control connection, a data-stream socket,
  an RSP local system), each recording the exchange;
- `runner`: runs cases, concurrently where they share no state, each bounded in time;
- `targets`: what is under test, and the embedded reference when nothing is named;
- `reports`: the summary, JSON, JUnit XML, baselines.
"""
