"""The text and JSON forms of records and of the analysis.

Text: one summary line per message (`record_text`) —

    number  seconds  source → destination  PROTOCOL  method/status/type  key fields

then the analysis (`analysis_text`). JSON: JSON Lines, one object per message (`record_json`), then
one last object whose only key is `"analysis"` (`analysis_json`). A message's `"fields"` is its
full field tree, in the form of the vectors (`fields_json`; vectors/rctp/README.md,
vectors/rsp/README.md): a data-stream packet as `{"sequence", "tag", "timestamp", "payloads"}`, an
RSP packet as `{"header", "body"}`, with NTP times and tags as hexadecimal strings and bytes as
hexadecimal.
"""
