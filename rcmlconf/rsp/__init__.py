"""RSP, the Robot Simulacrum Protocol (specs/rsp.md): the robot model, and the protocol without I/O.

- `model`: a robot model as data (D-RSP-1 to D-RSP-7); `rcmlconf validate` loads `.rmodel` files.
- `layout`: what each Device Map bit means for each kind of device and packet (D-RSP-14).
"""
