"""One declaration of every packed layout (``physics.layout``), and one kernel interface.

Walks every :class:`~spinstrike.physics.layout.Table`: column names are unique, each module
constant equals its column, the world's buffer fields do not share a slot, and no kernel
addresses a packed column with a literal number. Also checks that no package reaches into
another package's private attributes (the envs use ``World``'s public kernel interface).
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import numpy as np
import pytest

import spinstrike
from spinstrike.physics.layout import FLOAT_FIELDS, INT_FIELDS, TABLES

ROOT = Path(spinstrike.__file__).resolve().parent.parent
PACKAGES = ("physics", "envs", "agents", "benchmarks")


def _modules(package: str):
    for path in sorted((ROOT / package).glob("*.py")):
        yield path, f"spinstrike.{package}.{path.stem}"


def _kernel_modules():
    """Every module that compiles kernels (it imports the one jit decorator module)."""
    for package in ("physics", "envs"):
        for path, name in _modules(package):
            if "from spinstrike.physics.jit import" in path.read_text():
                yield path, name


KERNEL_MODULES = list(_kernel_modules())
for _path, _name in KERNEL_MODULES:
    importlib.import_module(_name)  # declares their tables

#: arrays whose last axis is a packed row (a Table): indexed by name only
PACKED = {"S", "Pm", "F", "HW", "hw", "MAT", "crec", "rec", "fcfg", "icfg", "stats", "row",
          "tbuf", "kcfg", "sbuf", "scfg", "trace", "ctrace", "tcount", "geo", "fbuf", "ibuf"}


def test_kernel_modules_are_found():
    names = {n.rsplit(".", 1)[1] for _, n in KERNEL_MODULES}
    assert {"contacts", "events", "impulse", "jam", "motion", "solvers", "kernels", "world",
            "fast"} <= names


@pytest.mark.parametrize("table", sorted(TABLES.values(), key=lambda t: t.name),
                         ids=lambda t: t.name)
def test_every_constant_is_its_column(table):
    """Each column's constant (``prefix + NAME``) exists once among the kernel modules and
    equals the column's offset; blocks are contiguous and the width is the sum."""
    modules = [importlib.import_module(n) for _, n in KERNEL_MODULES]
    modules.append(importlib.import_module("spinstrike.physics.layout"))
    expected = 0
    for column in table.names:
        assert table[column] == expected, (table.name, column)
        expected += table.widths[column]
        const = table.constant(column)
        values = {getattr(m, const) for m in modules if hasattr(m, const)}
        assert values == {table[column]}, (table.name, column, const, values)
    assert len(table) == expected


def test_no_constant_names_two_columns():
    owners: dict[str, str] = {}
    for table in TABLES.values():
        for column in table.names:
            const = table.constant(column)
            assert const not in owners, f"{const}: {owners.get(const)} and {table.name}"
            owners[const] = table.name


@pytest.mark.parametrize("pucks", [0, 8], ids=["few bodies", "calendar"])
def test_buffer_fields_share_no_slot(pucks):
    """Every float and int field of a world owns its own slots of the packed buffers (the
    calendar's fields are empty below ``layout.CALENDAR_BODIES`` bodies)."""
    from spinstrike.physics import World

    extra = [{"name": f"p{k}", "shape": "disk", "radius": 0.01, "mass": 1,
              "position": [-0.4 + 0.05 * k, -0.4]} for k in range(pucks)]
    w = World({"effects": ["rotation", "walls"], "table": {"size": [1, 1]},
               "bodies": [{"name": "a", "shape": "disk", "radius": 0.1, "mass": 1},
                          {"name": "b", "shape": "rod", "length": 0.3, "mass": 1,
                           "position": [0.3, 0]}, *extra]}, batch_size=3)
    for table, buf in ((FLOAT_FIELDS, w.buffers.fbuf), (INT_FIELDS, w.buffers.ibuf)):
        owner = np.full(buf.shape, -1)
        for k, name in enumerate(table.names):
            view = getattr(w, "_" + name)
            if view.size == 0:
                assert not pucks and name in ("calf", "cali", "pair_index"), name
                continue
            assert np.shares_memory(view, buf)
            start = (view.__array_interface__["data"][0]
                     - buf.__array_interface__["data"][0]) // buf.itemsize
            slots = owner[start:start + view.size]
            assert (slots == -1).all(), f"{name} overlaps {table.names[slots.max()]}"
            slots[:] = k


def _literal_columns(path: Path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name)
                and node.value.id in PACKED):
            continue
        index = node.slice
        last = index.elts[-1] if isinstance(index, ast.Tuple) else index
        if isinstance(last, ast.Slice):
            continue
        for sub in ast.walk(last):
            if isinstance(sub, ast.Constant) and isinstance(sub.value, int):
                yield node.lineno, ast.unparse(node)


def test_no_kernel_addresses_a_column_by_a_literal():
    bad = [f"{path.relative_to(ROOT)}:{line}: {text}" for path, _ in KERNEL_MODULES
           for line, text in _literal_columns(path)]
    assert not bad, "columns addressed by literal numbers:\n" + "\n".join(bad)


def test_the_literal_scan_catches_a_literal(tmp_path):
    bad = tmp_path / "k.py"
    bad.write_text("def f(S, row, T_OBS):\n    S[0, 3] = row[T_OBS + 1]\n")
    assert len(list(_literal_columns(bad))) == 2


def _definitions(package: str) -> set[str]:
    """Private names a package defines: functions, classes, attributes assigned anywhere."""
    names = set()
    for path, _ in _modules(package):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                names.add(node.name)
            elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
                names.add(node.attr)
            elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                names.add(node.id)
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                names.add(node.value)  # setattr/getattr by name, _VIEWS tuples
    return {n for n in names if n.startswith("_") and not n.startswith("__")}


def _private_accesses(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if (isinstance(node, ast.Attribute) and node.attr.startswith("_")
                and not node.attr.startswith("__")):
            owner = node.value
            if isinstance(owner, ast.Name) and owner.id in ("self", "cls"):
                continue
            if isinstance(owner, ast.Call) and ast.unparse(owner.func) == "super":
                continue
            yield node.lineno, node.attr, ast.unparse(node)


def test_no_package_reaches_into_another_packages_privates():
    """Outside the tests, ``x._name`` is only used where ``_name`` belongs to the same package
    (the envs go through World's public kernel interface: ``buffers``, ``run``, ``edit``)."""
    own = {p: _definitions(p) for p in PACKAGES}
    everyone = set().union(*own.values())
    bad = []
    for package in PACKAGES:
        for path, _ in _modules(package):
            for line, attr, text in _private_accesses(path):
                if attr in everyone and attr not in own[package]:
                    bad.append(f"{path.relative_to(ROOT)}:{line}: {text}")
    assert not bad, "private attributes of another package:\n" + "\n".join(bad)
