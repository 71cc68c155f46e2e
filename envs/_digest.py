"""The code digest of a user's module (``spinstrike.envs.code_fingerprint``): a hash of its
syntax tree in a form no Python version changes. Standard library only, so that a test can load
this file by its path under every Python it finds (``import spinstrike.envs`` needs numpy and
Gymnasium, and its physics numba).

A digest is written ``"<scheme>:<sha256>"``. The schemes before this one wrote the bare sha256:
``ast.dump``'s form (before commit 5c7fc06), which Python 3.13 changed (it leaves out empty
fields), then ``ast.unparse``'s text, which 3.12 changed (a quoted string inside an f-string's
braces, ``f"{d['a']}"``, prints ``f'{d['a']}'``: the same ``mylab.py`` read as changed under
3.12 against a run trained under 3.11, walk W24b F3). Neither is told from the other, nor
compared with this one (W24b F4: a run recorded at the previous commit read as changed)."""

from __future__ import annotations

import ast
import hashlib

#: the scheme of the digests this code writes
SCHEME = "ast-3"


def digest(tree: ast.Module) -> str:
    """``"ast-3:<sha256>"`` of module ``tree`` without its docstrings and top-level
    ``register(...)`` calls (``without_docs_and_registers``, which changes ``tree``), in the
    form of :func:`canonical`."""
    text = canonical(without_docs_and_registers(tree))
    return f"{SCHEME}:{hashlib.sha256(text.encode()).hexdigest()}"


def canonical(node) -> str:
    """``node`` as text no Python version (3.11 to 3.13) changes: each node as its type's name
    and its ``_fields`` in order, ``name=value``; a field that is None or an empty list is left
    out (so the fields newer Pythons added with such defaults, ``type_params``, ``TypeVar``'s
    ``default_value``, do not count, and 3.13's ``ast.dump`` leaving them out changes nothing);
    a constant by its ``repr``. An f-string is its nodes like any other's, not ``unparse``'s
    text, whose quotes 3.12 changed, its literal parts joined (``_joined``). No line numbers or
    columns (``_attributes``): a layout changes nothing."""
    if isinstance(node, ast.JoinedStr):
        node = ast.JoinedStr(values=_joined(node.values))
    if isinstance(node, ast.AST):
        fields = (f"{name}={canonical(value)}" for name in node._fields
                  if (value := getattr(node, name, None)) is not None and value != [])
        return f"{type(node).__name__}({','.join(fields)})"
    if isinstance(node, list):
        return f"[{','.join(canonical(item) for item in node)}]"
    return repr(node)


def _joined(values: list) -> list:
    """An f-string's parts with adjacent literal parts joined and empty ones left out: 3.12.1
    ends a nested format spec (``f"{x:>{4}}"``) with an empty ``Constant('')``, which 3.11
    and 3.13 do not write."""
    out: list = []
    for value in values:
        if isinstance(value, ast.Constant) and isinstance(value.value, str):
            if not value.value:
                continue
            if out and isinstance(out[-1], ast.Constant) and isinstance(out[-1].value, str):
                out[-1] = ast.Constant(value=out[-1].value + value.value)
                continue
        out.append(value)
    return out


def without_docs_and_registers(tree: ast.Module) -> ast.Module:
    """``tree`` without docstrings and top-level calls of Gymnasium's ``register``
    (``gym.register(...)``, ``gymnasium.register(...)``,
    ``gymnasium.envs.registration.register(...)``, or a ``register`` imported from gymnasium):
    a module's code as far as a run's record does not already hold it. Any other
    ``register(...)`` call counts (walk W25 F1: a reward hook set by ``HOOKS.register(...)``
    was left out, and an edit of it went unnoticed)."""
    gym_names = {"gymnasium", "gym"}  # what the module calls gymnasium (import ... as ...)
    bare = set()  # names that are gymnasium's register (from gymnasium import register as r)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.partition(".")[0] in ("gymnasium", "gym"):
                    gym_names.add((alias.asname or alias.name).partition(".")[0])
        elif isinstance(node, ast.ImportFrom) and (node.module or "").partition(".")[0] in (
                "gymnasium", "gym"):
            bare |= {alias.asname or alias.name for alias in node.names
                     if alias.name == "register"}

    def root(func) -> str | None:
        while isinstance(func, ast.Attribute):
            func = func.value
        return func.id if isinstance(func, ast.Name) else None

    def registers(node) -> bool:
        call = node.value if isinstance(node, ast.Expr) else None
        func = call.func if isinstance(call, ast.Call) else None
        return (isinstance(func, ast.Name) and func.id in bare) or (
            isinstance(func, ast.Attribute) and func.attr == "register"
            and root(func) in gym_names)

    tree.body = [n for n in tree.body if not registers(n)]
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                and body and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return tree
