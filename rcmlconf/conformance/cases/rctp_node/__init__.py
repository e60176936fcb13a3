"""rctp/node: READ and WRITE of a robot's nodes, and the node check before them (D-RCTP-25).

- `targets`: what READ gives, and the refusal of a target that cannot take the method.
- `unreadable`: READ of a node without `r`.
- `write_bodies`: WRITE bodies, right and wrong.
- `write_nodes`: the `Nodes` of a WRITE.
"""
