"""Wireshark support: a Lua dissector of RCTP/2.0 (control and data stream) and RSP.

- `lua`: `generate_lua(model)`, the plugin's text, generated from the tables of rcmlconf's codecs
  (as pymavlink's mavgen generates its Wireshark plugin from its message definitions); with a
  robot model, RSP's Device Map and payloads are decoded field by field.

`rcmlconf wireshark -o rcml.lua [--model M]` writes it; `tshark -X lua_script:rcml.lua` loads it.
"""

from rcmlconf.wireshark.lua import generate_lua

__all__ = ["generate_lua"]
