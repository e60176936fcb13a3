"""The reference RSP implementation (specs/rsp.md): a robot (`robot`) with simulated bodies
(`bodies`, `cubo`), and the local system's simulacrum (`simulacrum`)."""
