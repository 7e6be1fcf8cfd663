"""The kernels keep the rule that bounds their compile time (ARCHITECTURE.md, conventions):
a compiled function called from compiled code with a constant among its arguments is
compiled once more for that constant (numba types it as a literal), and with it everything
it calls. So no call from the kernels to a function compiled on its own passes a bare
constant (True, False, a number, a module's constant such as FORWARD), except to the small
leaves in LEAVES; `np.int64(FORWARD)` and `np.True_` are values of a type, and compile
once, and a call that unpacks a tuple (`f(n, *args, True)`) passes its arguments as one
tuple, whose types numba takes as they are, not as literals. numba shows a breach only when
it compiles from an empty cache, minutes later; the sources show it at once."""

import ast
from pathlib import Path

import numba
import numpy as np

PACKAGE = Path(__file__).resolve().parents[2] / "revdem_cli"
SOURCES = sorted(
    path
    for folder in ("kernels", "laws", "wall_shapes")
    for path in (PACKAGE / folder).glob("*.py")
)

COMPILERS = {"jit", "pjit", "by_size", "by_parts"}
"""What makes a function compiled on its own (`revdem_cli.kernels`); `inline` and
`inline_arrays` helpers are compiled into their callers."""

LEAVES = {"note", "note_overflow"}
"""Small compiled leaves that take an event's or a quantity's kind as a constant: a few small
builds, and no code beneath them."""


def _name(node: ast.AST) -> str | None:
    if isinstance(node, ast.Call):
        node = node.func
    if isinstance(node, ast.Name):
        return node.id
    return node.attr if isinstance(node, ast.Attribute) else None


def compiled_apart(tree: ast.Module) -> set[str]:
    """Names of a module's functions compiled on their own."""
    names = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            if any(_name(d) in COMPILERS for d in node.decorator_list):
                names.add(node.name)
        elif isinstance(node, ast.Assign) and _name(node.value) in COMPILERS:
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return names


def constants(tree: ast.Module) -> set[str]:
    """A module's constants: upper-case names bound to a bool or a number."""
    names = set()
    for node in tree.body:
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Constant):
            if isinstance(node.value.value, bool | int | float):
                names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return {name for name in names if name.isupper()}


def is_constant(argument: ast.AST, names: set[str]) -> bool:
    if isinstance(argument, ast.Constant):
        return isinstance(argument.value, bool | int | float)
    return _name(argument) in names and isinstance(argument, ast.Name | ast.Attribute)


def literal_calls(sources: list[Path]) -> list[str]:
    """Each call, in `sources`, of a function compiled on its own with a bare constant among
    its arguments, but for LEAVES and calls that unpack a tuple: 'file:line
    callee(constant)'."""
    trees = {path: ast.parse(path.read_text()) for path in sources}
    apart = set().union(*(compiled_apart(tree) for tree in trees.values())) - LEAVES
    names = set().union(*(constants(tree) for tree in trees.values()))
    found = []
    for path, tree in trees.items():
        for node in ast.walk(tree):
            if not isinstance(node, ast.Call) or _name(node) not in apart:
                continue
            if any(isinstance(argument, ast.Starred) for argument in node.args):
                continue
            for argument in [*node.args, *(k.value for k in node.keywords)]:
                if is_constant(argument, names):
                    place = f"{path.name}:{node.lineno}"
                    found.append(f"{place} {_name(node)}({ast.unparse(argument)})")
    return found


def test_no_compiled_call_from_the_kernels_takes_a_bare_constant():
    assert literal_calls(SOURCES) == []


def test_the_check_finds_a_constant_where_there_is_one(tmp_path):
    source = tmp_path / "kernel.py"
    source.write_text(
        "FORWARD = 0\n"
        "@jit\n"
        "def heavy(mode, keep):\n"
        "    return mode\n"
        "@jit\n"
        "def caller(x):\n"
        "    heavy(FORWARD, np.True_)\n"
        "    heavy(np.int64(FORWARD), True)\n"
        "    note(x, FORWARD)\n"
        "    heavy(*x, True)\n"
    )
    assert literal_calls([source]) == ["kernel.py:7 heavy(FORWARD)", "kernel.py:8 heavy(True)"]


def test_a_constant_compiles_a_function_anew_and_a_typed_value_does_not():
    """What the rule rests on, in numba as revdem runs it."""

    @numba.njit
    def leaf(flag, mode):
        return mode + 1 if flag else mode

    @numba.njit
    def caller(flag):
        unpacked = (np.int64(3),)
        typed = leaf(flag, np.int64(1)) + leaf(np.True_, np.int64(2)) + leaf(True, *unpacked)
        return typed + leaf(True, 1)

    caller(False)
    assert len(leaf.overloads) == 2  # (bool, int64) and (Literal True, Literal 1)
