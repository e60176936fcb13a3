"""RSP sessions without I/O (specs/rsp.md §2-§4): the local system's side (`local.LocalEndpoint`)
and the robot's (`robot.RobotEndpoint`), over `wire.SessionWire` (numbering, replay window,
sealing) and `timing` (the beat every T, link loss and session timeout). `events` lists what they
tell their applications."""
