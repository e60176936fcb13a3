"""pcap files, read and written.

- `reader`: `Capture`, the packet records of a pcap or pcapng file; `classic` and `pcapng` read
  the two formats, `records` names a record and the errors of reading one.
- `frames`: a frame's link layer and its IPv4/IPv6, TCP and UDP headers (`FrameDecoder`), IP
  fragments put together by `fragments`; `addresses` writes their addresses as text.
- `writer`: makes one from payloads an application sent and received (the harness's
  --capture), with the IPv4, TCP and UDP headers the kernel would have put round them.
"""
