"""What a run reports: `summary` (counts and the failures' explanations, for the terminal),
`json_report` (--json), `junit` (--junit), `baseline` (--baseline), `capture` (--capture)."""
