"""The cases, one module an area: `rctp_messages` holds `rctp/msg/...`, and so on. Every module
here is imported by `registry.all_cases`."""
