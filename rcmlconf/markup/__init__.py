"""Reading XML documents safely (specs/xml.md) and checking them against element tables.

`parse_document` refuses hostile input before libxml2 sees it; `Checker` walks a parsed tree
against a language's element table and collects located diagnostics.
"""
