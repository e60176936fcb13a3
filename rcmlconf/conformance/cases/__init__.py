"""The conformance cases: one module an area, named after the area's ID.

`rctp_msg` holds every `rctp/msg/...` case, `rsp_local` every `rsp/local/...` case, and so on.
A big area is a package (`rctp_client/`), with a submodule a topic. A module whose name starts
with `_` holds helpers and no cases. `registry.all_cases` imports every module here.
`rcmlconf cases --where ID` prints the file and line of a case.
"""
