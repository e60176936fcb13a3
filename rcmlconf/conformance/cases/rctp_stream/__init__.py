"""rctp/stream: stream accesses and their data stream (specs/rctp-2.0.md §5, §6).

- `setup`: SETUP and its Transport.
- `packets`: the DATA packets a server sends.
- `play`: what GO, PAUSE and STOP do to the DATA.
- `writes`: the DATA a client writes, and the receive timeout.
- `dropped`: the packets a server drops or skips.
- `stop`: a server's STOP that the client refuses.
"""
