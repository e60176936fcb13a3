"""`read` and `write`: one request over the control connection (D-RCTP-17), and what it targets.

A person names the data node or event access they mean; which request that is depends on the
node's access: a data node of a normal access is read and written itself, one of an event access
through the access with `Nodes:` naming it, and a stream's nodes travel on the data stream only.
Each `plan_*` works that out from the model before anything is sent, so a mistake on the command
line is a usage error, not a request the server refuses.
"""

from __future__ import annotations

from collections.abc import Sequence

import click

from rcmlconf.cli.client.running import Options, Work
from rcmlconf.cli.client.values import (
    parse_assignments,
    parse_node_value,
    value_text,
    values_json,
)
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, RcmlDocument
from rcmlconf.reference.client.adapter import Client, RctpError
from rcmlconf.values import Value


def access_of(model: RcmlDocument, node: DataNode) -> AccessNode:
    access = model.node(node.path.rsplit("/", 1)[0])
    assert isinstance(access, AccessNode)  # a data node's parent is its access (D-RCML-5)
    return access


def use_stream(path: str, access: AccessNode) -> click.UsageError:
    return click.UsageError(
        f"{path} travels on the data stream of {access.path}, not over the control connection:"
        f" use `stream {access.path}`"
    )


def plan_read(options: Options, model: RcmlDocument, path: str) -> Work:
    node = model.node(path)
    if isinstance(node, DataNode):
        access = access_of(model, node)
        if access.type is AccessType.STREAM:
            raise use_stream(path, access)
        return _reading(options, path, (node,))  # an event's node: the client reads its access
    if isinstance(node, AccessNode) and node.type is AccessType.EVENT:
        return _reading(options, path, node.data)
    if isinstance(node, AccessNode) and node.type is AccessType.STREAM:
        raise use_stream(path, node)
    return _unlisted(path)


def _reading(options: Options, target: str, nodes: Sequence[DataNode]) -> Work:
    output = options.output

    async def read(client: Client) -> int:
        values = await client.read(target)
        if options.json:
            output.json(values_json(nodes, values))
            return 0
        for node in nodes:
            if node.name in values:
                text = value_text(node, values[node.name])
                output.out.line([(node.name, "bold"), (f" = {text}", "")])
        return 0

    return read


def _unlisted(path: str) -> Work:
    """READ of what the model has no readable node at: the server's answer (404, 405) says
    why, and a yes means the model is not this robot's."""

    async def read(client: Client) -> int:
        await client.request("READ", path)
        raise RctpError(
            f"READ {path}: the server answered 200, but the RCML has no data node or event access"
            " there: is it this robot's?"
        )

    return read


def plan_write(
    options: Options, model: RcmlDocument, path: str, texts: Sequence[str], acquire: bool
) -> Work:
    node = model.node(path)
    try:
        if isinstance(node, DataNode):
            access = access_of(model, node)
            if access.type is AccessType.STREAM:
                raise use_stream(path, access)
            if len(texts) != 1:
                raise click.UsageError(f"{path} is one data node: give one VALUE")
            values: dict[str, Value] = {node.name: parse_node_value(node, texts[0])}
        elif isinstance(node, AccessNode) and node.type is AccessType.EVENT:
            if not texts:
                raise click.UsageError(f"{path} is an event access: give name=value for its nodes")
            values = parse_assignments(node, texts)
        elif isinstance(node, AccessNode) and node.type is AccessType.STREAM:
            raise use_stream(path, node)
        else:
            raise click.UsageError(f"the RCML has no data node or event access {path}")
    except ValueTextError as exc:
        raise click.UsageError(str(exc)) from None

    async def write(client: Client) -> int:
        if acquire:
            await client.acquire(path)
        await client.write(path, values)
        return 0

    return write
