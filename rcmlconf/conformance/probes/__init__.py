"""What cases talk to a target with. Each probe records what it sends and receives in the case's
transcript, and turns a target that does not answer, or answers what cannot be parsed, into the
case's `Failed` with the requirement that answer broke."""
