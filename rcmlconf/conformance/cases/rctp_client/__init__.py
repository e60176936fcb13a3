"""rctp/client: the cases of an RCTP/2.0 client under test (`--role client`).

The harness plays the server. Each module holds one topic:

- `answers`: how the client answers the server's WRITE, STOP and BYE, and broken answers.
- `grammar`: malformed requests from the server.
- `scenario`: what the client sends while it runs D-RCTP-31's scenario.
- `pushes`: the server's data-change WRITEs (D-RCTP-27).
- `streams`: the client's data stream, FLOW answers, heartbeats and clock estimate.
- `stream_data`: what the client does with the played robot's DATA.
- `documents`: how the client reads the robot's RCML (D-RCTP-31 step 1).
"""
