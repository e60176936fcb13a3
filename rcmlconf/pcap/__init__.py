"""pcap files: `writer` makes one from payloads an application sent and received (the harness's
--capture), with the IPv4, TCP and UDP headers the kernel would have put round them."""
