"""The shipped DTDs and XSDs (rcmlconf/schemas) against the code and every vector.

specs/README.md: a requirement tagged `xsd` (or `dtd`) is one the shipped XSD (DTD) enforces on
its own. So each schema must declare exactly the elements and attributes of the code's element
tables, accept every document the validator accepts, reject every vector whose errors are all
tagged for it, and agree with the code's lexical forms on every attribute value.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from functools import cache
from importlib.resources import files

import pytest
import xmlschema
from lxml import etree
from support.xml_vectors import XmlVector, xml_vectors
from xmlschema.validators import XsdAnyAttribute, XsdAnyElement, XsdElement

from rcmlconf.errors import ValueTextError
from rcmlconf.markup.lexical import Enumeration, ncname
from rcmlconf.markup.structure import Attr, TextParser
from rcmlconf.rcml.schema import ELEMENTS as RCML_ELEMENTS
from rcmlconf.rsp.schema import ELEMENTS as RSP_ELEMENTS
from rcmlconf.rsp.schema import FIELD_HOLDERS
from rcmlconf.rxid.schema import ELEMENTS as RXID_ELEMENTS
from rcmlconf.specs import requirements
from rcmlconf.validate.languages import LANGUAGES

#: Each language's element table, by root element.
TABLES = {"rcml": RCML_ELEMENTS, "rxid": RXID_ELEMENTS, "robotModel": RSP_ELEMENTS}
#: The file names of each language's schemas, but for .dtd and .xsd: its DTD's (D-XML-3).
SCHEMAS = {root: LANGUAGES[root].dtd.removesuffix(".dtd") for root in TABLES}
REQUIREMENTS = requirements()
#: Every implementation of a language's schemas; the part before "/" is the check of specs/.
CHECKS = ("dtd", "xsd/lxml", "xsd/xmlschema")
#: Refused before or while parsing: there is no tree to validate.
UNPARSED = {"R-XML-1", "R-XML-2", "R-XML-5", "R-XML-6"}
#: The DTDs' content model for "holds nothing but white space and comments" names this element
#: and never declares it, so that no element can stand there.
NO_CHILDREN = "no-children-here"
PARSER = etree.XMLParser(resolve_entities=False, load_dtd=False, no_network=True)

Errors = Callable[[etree._ElementTree], list[str]]


def schema_text(name: str) -> bytes:
    return (files("rcmlconf") / "schemas" / name).read_bytes()


@cache
def xmlschema_xsd(language: str) -> xmlschema.XMLSchema10:
    return xmlschema.XMLSchema10(schema_text(f"{SCHEMAS[language]}.xsd").decode())


@cache
def checks(language: str) -> dict[str, Errors]:
    """Each check of CHECKS as a function from a tree to its error log (empty: valid)."""

    def libxml2(schema: etree.DTD | etree.XMLSchema) -> Errors:
        return lambda tree: [] if schema.validate(tree) else [str(e) for e in schema.error_log]

    xsd = xmlschema_xsd(language)
    dtd, xsd_text = (schema_text(f"{SCHEMAS[language]}{suffix}") for suffix in (".dtd", ".xsd"))
    return {
        "dtd": libxml2(etree.DTD(io.BytesIO(dtd))),
        "xsd/lxml": libxml2(etree.XMLSchema(etree.fromstring(xsd_text))),
        "xsd/xmlschema": lambda tree: [f"{e.path}: {e.reason}" for e in xsd.iter_errors(tree)],
    }


def tagged(rule: str, check: str) -> bool:
    """Whether specs/ says the schema of `check` enforces `rule`."""
    return bool(rule) and check.split("/")[0] in REQUIREMENTS[rule].checks


def accepts(parse: TextParser | None, text: str) -> bool:
    """Whether the code takes `text` as the value of an attribute of that lexical form."""
    if parse is not None:
        try:
            parse(text)
        except ValueTextError:
            return False
    return True


def choices(parse: TextParser | None) -> frozenset[str] | None:
    """The texts an enumerated attribute allows."""
    return frozenset(parse.choices) if isinstance(parse, Enumeration) else None


# -- the schemas load ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", [f"{n}{s}" for n in SCHEMAS.values() for s in (".dtd", ".xsd")])
def test_schema_loads(name: str) -> None:
    if name.endswith(".dtd"):
        etree.DTD(io.BytesIO(schema_text(name)))
    else:
        etree.XMLSchema(etree.fromstring(schema_text(name)))
        xmlschema.XMLSchema10(schema_text(name).decode())  # raises on any error in the schema


# -- they declare the element tables ---------------------------------------------------------------


def expected_attributes(language: str) -> dict[str, dict[str, tuple[bool, frozenset[str] | None]]]:
    """Per element, per attribute: required, and the values of an enumeration."""
    return {
        element: {
            name: (attr.required, choices(attr.parse)) for name, attr in spec.attributes.items()
        }
        for element, spec in TABLES[language].items()
    }


def dtd_type(attr: Attr) -> str:
    return "enumeration" if choices(attr.parse) else "id" if attr.parse is ncname else "cdata"


def content_names(content: etree._DTDElementContentDecl | None) -> set[str]:
    if content is None:
        return set()
    own = {content.name} if content.type == "element" else set()
    return own | content_names(content.left) | content_names(content.right)


@pytest.mark.parametrize("language", TABLES)
def test_dtd_declares_the_element_table(language: str) -> None:
    dtd = etree.DTD(io.BytesIO(schema_text(f"{SCHEMAS[language]}.dtd")))
    found = {
        element.name: {
            a.name: (a.default == "required", frozenset(a.values()) or None)
            for a in element.iterattributes()
        }
        for element in dtd.iterelements()
    }
    assert found == expected_attributes(language)
    for element in dtd.iterelements():
        spec = TABLES[language][element.name]
        # Element content: white space and comments, never text (R-XML-9); EMPTY is too strict.
        assert element.type == "element", f"<{element.name}> has {element.type} content"
        assert content_names(element.content) - {NO_CHILDREN} == spec.children, element.name
        for a in element.iterattributes():
            assert a.type == dtd_type(spec.attributes[a.name]), f"{element.name}/@{a.name}"
            assert a.default in ("required", "implied"), f"{element.name}/@{a.name} is defaulted"


def is_extension(wildcard: XsdAnyElement | XsdAnyAttribute) -> bool:
    """Any namespace but none, skipped (D-XML-6)."""
    return set(wildcard.namespace) == {"##other"} and wildcard.process_contents == "skip"


@pytest.mark.parametrize("language", TABLES)
def test_xsd_declares_the_element_table(language: str) -> None:
    found: dict[str, dict[str, tuple[bool, frozenset[str] | None]]] = {}
    for element in xmlschema_xsd(language).iter_components(XsdElement):
        attributes = {}
        for name, attribute in element.attributes.items():
            if name is None:  # the wildcard: extensions in any other namespace (D-XML-6)
                assert is_extension(attribute), f"<{element.name}>: {attribute}"
                continue
            values = attribute.type.enumeration or ([attribute.fixed] if attribute.fixed else [])
            attributes[name] = (attribute.use == "required", frozenset(values) or None)
        assert found.setdefault(element.name, attributes) == attributes, element.name
        children = list(element.iterchildren())
        spec = TABLES[language][element.name]
        assert {c.name for c in children if isinstance(c, XsdElement)} == spec.children
        wildcards = [c for c in children if isinstance(c, XsdAnyElement)]
        assert wildcards, f"<{element.name}> takes no extension elements"
        assert all(is_extension(w) for w in wildcards), f"<{element.name}>: {wildcards}"
        assert None in element.attributes, f"<{element.name}> takes no extension attributes"
    assert found == expected_attributes(language)


# -- every vector ----------------------------------------------------------------------------------


def uses_namespaces(tree: etree._ElementTree) -> bool:
    return any(
        element.nsmap or "{" in element.tag or any("{" in name for name in element.attrib)
        for element in tree.getroot().iter(etree.Element)
    )


#: Faults of the xmlschema package (4.3), each with the text of libxml2's error for the same
#: document: where libxml2 refuses a document for that alone, xmlschema's acceptance is its bug.
XMLSCHEMA_DEFECTS = {
    "'group-sibling-names'": (
        "xmlschema keeps one state per identity constraint, so the constraint of a group that "
        "holds a group loses its scope: it misses the group's duplicate names"
    ),
    "Character content other than whitespace": (
        "xmlschema takes Python's white space for XML's: U+00A0 or U+3000 in element-only "
        "content passes"
    ),
}


def xmlschema_defect(language: str, tree: etree._ElementTree) -> str | None:
    """The known xmlschema fault that explains its accepting a tree libxml2 refuses, if any."""
    errors = checks(language)["xsd/lxml"](tree)
    for marker, defect in XMLSCHEMA_DEFECTS.items():
        if errors and all(marker in error for error in errors):
            return defect
    return None


@pytest.mark.parametrize("check", CHECKS)
@pytest.mark.parametrize("vector", xml_vectors(), ids=lambda vector: vector.id)
def test_vector(vector: XmlVector, check: str) -> None:
    if vector.error_rules & UNPARSED:
        pytest.skip("refused before or while parsing")
    try:
        tree = etree.parse(str(vector.path), PARSER)
    except etree.XMLSyntaxError:
        pytest.skip("not well-formed")
    language = tree.getroot().tag
    if language not in TABLES:
        pytest.skip("the root element is none of the languages'")
    if check == "dtd" and uses_namespaces(tree):
        pytest.skip("a DTD cannot allow namespaces: documents with any are DTD-invalid")
    errors = checks(language)[check](tree)
    if vector.valid:
        assert not errors, f"{check} rejects a valid document:\n" + "\n".join(errors)
        return
    rules = sorted(vector.error_rules)
    if not all(tagged(rule, check) for rule in rules):
        pytest.skip("some of its errors are not tagged for this schema")
    defect = xmlschema_defect(language, tree) if check == "xsd/xmlschema" else None
    if not errors and defect:
        pytest.xfail(defect)
    assert errors, f"{check} accepts a document whose errors {rules} are all tagged for it"


# -- every attribute value: the schemas and the code's lexical forms agree -------------------------

#: A value for each required attribute that every schema accepts; an enumerated one takes the
#: least of its choices.
REQUIRED_VALUES = {
    "site": "rctp://robot",
    "name": "n",
    "kind": "k",
    "href": "h",
    "content": "c",
    "dataPath": "/n/n",
    "caption": "c",
    "value": "1",
    "modelId": "1",
    "of": "n",
}
#: The child an element must hold one of (R-RXID-3, R-RXID-20, R-RSP-7).
FIRST_CHILD = {
    "rxid": "window",
    "radioGroup": "item",
    "popUpMenu": "item",
    **dict.fromkeys(FIELD_HOLDERS, "field"),
}
TEXTS = (
    *("", " ", "0", "1", "+1", "-1", "007", "+0", "1.5", ".5", "5.", "+.5E+3", "16e-3", "1E-4"),
    *("1e400", "1e-400", "INF", "-INF", "NaN", "0x10", "1_0", "1 0", " 1", "1 ", "\t1", "65535"),
    *("+065535", "65536", "2147483647", "+02147483647", "2147483648", "99999999999", "2.00"),
    *("n", "_n", ":n", "n:m", "-n", "1n", "n m", "n\u00b7", "\u2100", "n\u0e2f", "\U00010000"),
    *("\u00d7", "/n", "/n/m", "/", "//n", "/n/", "n/m", "/n m", "rctp://robot", "RCTP://h:1/p"),
    *("rctp://", "http://robot", "a|b", "a^b", "a`b", "a{b}", "a\\b", "a<b", 'a"b', "a\tb"),
    *("a\u0080b", "a\u007fb", "caf\u00e9", "a%20b#c"),
)


def attributes() -> list[tuple[str, str, str]]:
    return [
        (language, element, attribute)
        for language, table in TABLES.items()
        for element, spec in table.items()
        for attribute in spec.attributes
    ]


def skeleton(language: str, target: str) -> etree._Element:
    """A document every schema accepts, holding `target`; returns `target`'s element."""
    table = TABLES[language]
    parents: dict[str, str] = {}
    for parent, spec in table.items():
        for child in sorted(spec.children):
            parents.setdefault(child, parent)
    path = [target]
    while path[-1] != language:
        path.append(parents[path[-1]])
    chain = [etree.Element(language)]
    for name in [*reversed(path[:-1]), *([FIRST_CHILD[target]] if target in FIRST_CHILD else [])]:
        chain.append(etree.SubElement(chain[-1], name))
    for element in chain:
        spec = table[element.tag]
        for name in spec.required:
            listed = choices(spec.attributes[name].parse)
            element.set(name, min(listed) if listed else REQUIRED_VALUES[name])
    return chain[len(path) - 1]


@pytest.mark.parametrize("check", CHECKS)
@pytest.mark.parametrize(("language", "element", "attribute"), attributes())
def test_attribute_values_agree_with_the_code(
    language: str, element: str, attribute: str, check: str
) -> None:
    """Every value the code takes passes; where the rule is tagged, every other value fails."""
    attr = TABLES[language][element].attributes[attribute]
    target = skeleton(language, element)
    tree = target.getroottree()
    errors = checks(language)[check]
    baseline = errors(tree)
    assert not baseline, "the document without the value is refused:\n" + "\n".join(baseline)
    exact = tagged(attr.rule, check)
    wrong = []
    listed = sorted(choices(attr.parse) or ())
    for text in (*TEXTS, *(v for c in listed for v in (c, c.upper(), f" {c}", f"{c} "))):
        target.set(attribute, text)
        log = errors(tree)
        if accepts(attr.parse, text):
            if log:
                wrong.append(f"{text!r} is refused, though the code takes it: {log[0]}")
        elif exact and not log:
            wrong.append(f"{text!r} passes, though the code refuses it")
    assert not wrong, "\n".join(wrong)
