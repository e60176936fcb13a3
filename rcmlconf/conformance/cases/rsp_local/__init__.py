"""rsp/local: the cases of an RSP local system under test (`--role local`).

The harness plays the robot. The local system runs the scenario of D-RSP-24 once a case.

- `session`: HELLO, the header, a DOWNLINK every T, events, BYE; and the helpers all share.
- `header`: the header against what the robot did.
- `pace`: the period, and a lost link.
- `receiving`: what the local system does with what it receives.
- `sending`: how it sends its own commands and memory commands.
"""
