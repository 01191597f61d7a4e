"""Mutation testing of mitlc's core modules: would the tests notice a wrong answer?

Each mutant changes one operator or constant of one module (``<`` to ``<=``, ``+`` to
``-``, ``and`` to ``or``, ``not x`` to ``x``, ``n`` to ``n + 1``, ``True`` to ``False``,
a call statement to ``pass``, ...). The module's own tests run against it in a scratch
copy of the repository; the mutant is *killed* when a test fails (or the tests time
out), and *survives* when they all pass. A survivor is behaviour no test pins down,
or an equivalent mutant (one that cannot change any result: say why in
``EQUIVALENT``).

    python tests/mutation.py                            # every module, 45 mutants each, 2 jobs
    python tests/mutation.py --module compile --sample 100 --seed 3 --jobs 2
    python tests/mutation.py --module parse --list      # the mutation points, without running
    python tests/mutation.py --module timed --sample 60 --seed 35 --record   # and docs/reliability.md's table

Prints a line per mutant and a table of kill rates (killed / non-equivalent). Sampling
is seeded: the same ``--seed`` draws the same mutants while the module is unchanged.
"""

from __future__ import annotations

import argparse
import ast
import datetime
import json
import os
import platform
import random
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RECORD = ROOT / "docs" / "mutation.json"
"""The last recorded run of each module (``--record``), from which docs/reliability.md's table is written."""
PAGE = ROOT / "docs" / "reliability.md"
TABLE_BEGIN = "<!-- the mutation table: written by python tests/mutation.py --record; edit the script -->"
TABLE_END = "<!-- end of the mutation table -->"

TARGETS: dict[str, tuple[str, list[str]]] = {
    "compile": (
        "mitlc/petri/compile.py",
        [
            "test_compile.py",
            "test_compile_props.py",
            "test_violations.py",
            "test_net_vs_monitor.py",
            "test_golden.py",
            "test_sparse.py",
        ],
    ),
    "runtime": (
        "mitlc/runtime/netruntime.py",
        ["test_runtime.py", "test_net_vs_monitor.py", "test_sacpn.py", "test_sparse.py"],
    ),
    # the runtime's pieces, split out of one file by issue 30: the same tests
    "rule": ("mitlc/runtime/rule.py", ["test_runtime.py", "test_net_vs_monitor.py", "test_sparse.py"]),
    "tables": ("mitlc/runtime/tables.py", ["test_runtime.py", "test_net_vs_monitor.py", "test_sparse.py"]),
    "obligations": ("mitlc/runtime/obligations.py", ["test_timed_contract.py", "test_net_vs_monitor.py"]),
    "reward": (
        "mitlc/petri/reward.py",
        ["test_reward.py", "test_compile.py", "test_compile_props.py", "test_runtime.py", "test_violations.py"],
    ),
    "monitor": ("mitlc/monitor/offline.py", ["test_monitor.py", "test_net_vs_monitor.py", "test_passes.py"]),
    "kernels": ("mitlc/monitor/kernels.py", ["test_monitor.py", "test_net_vs_monitor.py", "test_passes.py"]),
    "parse": ("mitlc/spec/parse.py", ["test_parse.py", "test_inline_predicates.py", "test_gym_plants.py"]),
    # the parser's pieces, split out of parse.py by issue 30: the same tests
    "transform": ("mitlc/spec/transform.py", ["test_parse.py", "test_inline_predicates.py"]),
    "checks": ("mitlc/spec/checks.py", ["test_parse.py", "test_deep_and_messages.py"]),
    "passes": ("mitlc/spec/passes.py", ["test_passes.py", "test_compile.py", "test_parse.py"]),
    # issue 35: the obligation trees of nested intervals, SACPN's fused trial kernel, the online
    # monitor and the graded rewards (the fastest tests first: -x stops at the first failure)
    "timed": (
        "mitlc/petri/timed.py",
        [
            "test_timed_parts.py",
            "test_net_vs_monitor.py",
            "test_obligation_kernel.py",
            "test_runtime.py",
            "test_timed_contract.py",
        ],
    ),
    "fused": ("mitlc/learn/sacpn/kernel.py", ["test_kernel.py"]),
    "online": ("mitlc/monitor/online.py", ["test_online.py", "test_scalar_monitor.py", "test_gym.py"]),
    "grades": ("mitlc/spec/grades.py", ["test_grades.py", "test_reward.py", "test_violations.py"]),
}
"""Module -> (its file, its own tests)."""

SELECT: dict[str, str] = {
    # the fused kernel's tests less the compiled trials past the first spec's (each compiles a
    # kernel for several seconds, and the uncompiled kernel, its same Python code, is compared
    # with numpy on every spec): a survivor costs 40 s instead of 2 minutes
    "fused": "not test_compiled_kernel_with_timed_obligations and not test_compiled_kernel_variants"
    " and not portable_process and not timed_obligations_train_on_the_kernel and not test_two_inputs_compiled",
}
"""Module -> the ``pytest -k`` expression that selects from its tests, where not all are run."""

_BLOCKS = "the blocked until scan is correct for any block size >= 1: B only trades time for memory"
_FAST = "switches between a fast path and the reference path, which compute the same values (tested to agree)"
_ROOT_FIRST = "the root's values at samples 0 .. 1 begin with sample 0's: [:, 0] is the same"
_AT_K = "a value at the prefix's last sample (q = k) is never kept as final either way"
_ONE_COLUMN = "the last sample's window has one column: [:, :2] is [:, :1]"
_FIRST_WIDTH = "the atom buffers are replaced at the first sample (capacity 0): their first width is never read"
_NONE_AS_0 = "a monotony of None is read as 0 (neither) wherever one is compared"
_FALSY = "None is falsy as False: the result is read as a truth value (any, not)"
_SEALED = "the sealed block ends k - h: its values are final, and keeping them as final changes none"
_SAME_SIZE = "grows the array to the size it has: the same values"
_NO_CODE = "a place code that never occurs (the root is never idle, a node below it never met or failed)"
_REGION = "a region sub-net taken for another is stepped by the scanning rule: same markings"
_UNREAD_COUNTS = "compact tables never have counting places: their increments are never read"
_RESHAPE = "numpy reads any negative size in reshape as the one to infer"
_EARLY_EXIT = "an early exit of the reachability search; the final size check refuses the same nets"
_FALLBACK = "the fallback position of a node built without one; the parser gives every node its own"
EQUIVALENT: dict[str, str] = {
    "kernels:<module>:const:64->65:_SMALL = 64": "_SMALL only picks the plain loop or the blocked scan below it;"
    " both give the same",
    "kernels:until_unbounded:bin:Add->Sub:math.isqrt(L - 1) + 1": _BLOCKS,
    "kernels:until_unbounded:bin:Sub->Add:L - 1#2": _BLOCKS,
    "kernels:until_unbounded:const:1->2:math.isqrt(L - 1) + 1": _BLOCKS,
    "kernels:until_unbounded:const:1->2:L - 1#2": _BLOCKS,
    "kernels:until:bool:Or->And:hi < lo or lo > L - 1": "an early return for an empty or out-of-trace window:"
    " the general path gives bottom",
    "monitor:_first:const:1->2:b + 1": "_first reads one sample past b only where b is the trace's end or a hit lies"
    " in [a, b]",
    "kernels:until:bin:Sub->Add:L - 1": "L + 1 for L - 1: a window covering the trace meets a U b with F b, which it"
    " implies (the other Sub there, hi + lo, is killed by test_until_windows_and_empty_intervals_on_long_traces)",
    "kernels:until:cmp0:Gt->GtE:lo > 0": "with lo = 0 the left side's window [0, -1] is empty: meeting with top"
    " changes nothing",
    "parse:_run:if:negated:isinstance(inner, MitlError)": "lark raises an inline transformer's errors unwrapped:"
    " its VisitError branch is never run",
    "checks:check_weights:const:1->2:A.Pos(1, 1)": _FALLBACK,
    "checks:check_weights:const:1->2:A.Pos(1, 1)#2": _FALLBACK,
    "checks:check_weights:bool:Or->And:node.pos is None or node.child.pos is None": "both positions are set by the"
    " parser whenever either is",
    "parse:_parse_spec.check_vars:const:1->2:A.Pos(1, 1)": _FALLBACK,
    "parse:_parse_spec.check_vars:const:1->2:A.Pos(1, 1)#2": _FALLBACK,
    "parse:_parse_spec:if:negated:name not in PLANTS": "looking up installed plants' entry points also when the name"
    " is known changes nothing",
    "reward:Neg.__str__:const:1->2:_NEG + 1": "no node has the precedence between a negation's and the next: +1 and"
    " +2 wrap the same",
    "reward:RExpr:const:9->10:prec = 9": "the precedence of atoms only needs to be the highest: 9 or 10 prints the"
    " same",
    "runtime:NetRuntime.advance_code:if:negated:not self.timed": "advance_code on a net without timed parts: the"
    " timed update of no tree is the identity",
    "runtime:NetRuntime.charge_code:if:negated:self.tables is not None and self.tables.charge is not None": _FAST,
    "runtime:NetRuntime.trace_markings:if:negated:self.tables is None": _FAST,
    "runtime:NetRuntime.obligation_arrays:bool:And->Or:self.dt is not None and self.steps is not None": "an assert"
    " that holds either way (both are set together)",
    "runtime:NetRuntime.__init__:const:0->1:np.zeros(0)": "the clock ends are read only by compact tables, which"
    " set them",
    "runtime:NetRuntime.encode:bool:And->Or:self.tables is not None and self.tables.index is not None": "an assert"
    " that holds either way (compact tables always carry their index)",
    "runtime:NetRuntime.clock_code:const:0->1:np.ndim(tau) == 0#2": "a 0-d array of the segment indexes the tables"
    " as its int does",
    "runtime:NetRuntime.__init__:bool:And->Or:p not in self._region_of and terms": "a transition into a region"
    " place has its region as guard: writing it twice is the same",
    "tables:build_compact:bin:FloorDiv->Div:MAX_TABLE // 16": "n * n <= MAX_TABLE // 16 and <= MAX_TABLE / 16"
    " agree on integers",
    "tables:build_compact:const:1.0->2.0:ends[0] - 1.0": "any time before the first clock end represents that stretch",
    "tables:build_compact:const:1->2:np.random.default_rng(20261201).integers(1, 2 ** 63, size=S, dtype=...": "the"
    " seed of the marking hash's weights: any seed hashes the same set apart",
    "tables:build_compact:const:0->1:(0, 0, 0)": _UNREAD_COUNTS,
    "tables:build_compact:const:0->1:(0, 0, 0)#2": _UNREAD_COUNTS,
    "tables:build_compact:const:0->1:(0, 0, 0)#3": _UNREAD_COUNTS,
    "tables:build_tables:const:1->2:(n_codes, 1)": "a second copy of the places' columns is never read: the"
    " expressions index the first",
    "tables:build_compact:const:1->2:-1": _RESHAPE,
    "grades:_box_grid:const:1->2:-1": _RESHAPE,
    "tables:build_compact.add:const:1->2:-1": _RESHAPE,
    "tables:build_compact.add:const:1->2:-1#2": _RESHAPE,
    "tables:build_tables:cmp0:Gt->GtE:n_clock_codes * n_codes * n_atom_codes > MAX_TABLE": _FAST,
    "tables:build_tables:cmp0:Gt->GtE:n_codes * n_codes > MAX_TABLE": _FAST,
    "tables:build_tables:bin:Mult->Div:n_clock_codes * n_codes * n_atom_codes": _FAST,
    "tables:build_tables:bin:Mult->Div:n_clock_codes * n_codes": _FAST,
    "tables:build_tables:bin:Mult->Div:n_codes * n_codes": _FAST,
    "tables:build_compact:bin:Mult->Div:done * n_segs * n_atom_codes": _EARLY_EXIT,
    "tables:build_compact:bin:Mult->Div:done * n_segs": _EARLY_EXIT,
    "rule:region_subnets:cmp0:IsNot->Is:term.clock is not None": _REGION,
    "rule:region_subnets:cmp0:IsNot->Is:term.age is not None": _REGION,
    "rule:region_subnets:cmp0:IsNot->Is:term.event is not None": _REGION,
    "online:_Running.values:cmp0:Lt->LtE:self.acc.shape[1] < m": _SAME_SIZE,
    "online:_RunningUntil.values:cmp0:Lt->LtE:have < m": _SAME_SIZE,
    "online:_Running.values:cmp0:Gt->GtE:f_new > self.f": "with f_new = f the block of newly sealed samples is"
    " empty: no window starts in it, nothing changes",
    "online:_Engine.__init__:const:1->2:-1": "advance() sets k before any value is read",
    "online:_Engine.vals:cmp0:LtE->Lt:q + g.h <= k": "a value kept as final one sample later: until then it is"
    " computed again, the same",
    "online:_Running.values:const:False->True:eng.vals(kid, first, k, fixed=False)": "the tail ends at k: no final"
    " value is ever stored or found for it",
    "online:_atom_names:call:removed:seen.add(id(n))": "a shared subformula visited again adds the same names",
    "online:_Node.__init__:const:0->1:lo=0": "nodes built without lo are no temporal operators: lo is never read",
    "online:_Node.__init__:const:0.0->1.0:hi=0.0": "nodes built without hi are no temporal operators: hi is never read",
    "online:_Node.__init__:const:False->True:value=False": "only constants read value, and each is built with its own",
    "online:_Engine._compute:const:2->3:(1, -1, 2)": "a node with an unbounded horizon is never constant (mono 2):"
    " 2 and 3 both miss it",
    "online:OnlineMonitor.reset:const:0->1:(self.R, 0)": _FIRST_WIDTH,
    "online:OnlineMonitor.reset:const:0->1:(self.R, 0)#2": _FIRST_WIDTH,
    "online:_monotone:return:None:0": _NONE_AS_0,
    "online:_monotone:return:None:0#2": _NONE_AS_0,
    "online:_growing:return:None:False": _FALSY,
    "online:_growing:return:None:False#2": _FALSY,
    "online:_RunningUntil.values:const:False->True:eng.vals(left, first, f_new, fixed=False)": _SEALED,
    "online:_RunningUntil.values:const:False->True:eng.vals(right, first, f_new, fixed=False)": _SEALED,
    "online:_Running.values:const:False->True:eng.vals(kid, first, f_new, fixed=False)": _SEALED,
    "online:OnlineMonitor.update:const:0->1:self._bool.vals(self._root, 0, 0)#2": _ROOT_FIRST,
    "online:OnlineMonitor.update:const:0->1:self._real.vals(self._root, 0, 0)#2": _ROOT_FIRST,
    "online:_Engine._compute:const:False->True:self.vals(g.kids[1], k, k, fixed=False)": _AT_K,
    "online:_Engine._compute:const:False->True:self.vals(kid, k, k, fixed=False)": _AT_K,
    "online:_Engine._compute:const:False->True:self.vals(kid, k, k, fixed=False)#2": _AT_K,
    "online:_Engine._compute:const:1->2::1": _ONE_COLUMN,
    "online:_Engine._compute:const:1->2::1#2": _ONE_COLUMN,
    "timed:<module>:const:1->2:-1": _NO_CODE,
    "timed:<module>:const:1->2:-1#2": _NO_CODE,
    "timed:<module>:const:1->2:-1#3": _NO_CODE,
}
"""A mutant that cannot change any result (its key: module, function, operator and the mutated
expression, as :func:`keys` writes it; no line number, so the list survives code moving) -> why.
``tests/test_mutation_keys.py`` checks that every key still names a mutation point."""

_SWAP_CMP = {
    ast.Lt: ast.LtE,
    ast.LtE: ast.Lt,
    ast.Gt: ast.GtE,
    ast.GtE: ast.Gt,
    ast.Eq: ast.NotEq,
    ast.NotEq: ast.Eq,
    ast.Is: ast.IsNot,
    ast.IsNot: ast.Is,
    ast.In: ast.NotIn,
    ast.NotIn: ast.In,
}
_SWAP_BIN = {
    ast.Add: ast.Sub,
    ast.Sub: ast.Add,
    ast.Mult: ast.Div,
    ast.Div: ast.Mult,
    ast.FloorDiv: ast.Div,
    ast.Mod: ast.FloorDiv,
    ast.BitAnd: ast.BitOr,
    ast.BitOr: ast.BitAnd,
}


@dataclass(frozen=True)
class Mutant:
    module: str
    index: int  # which mutation point, in the order the walk finds them
    line: int
    what: str
    key: str  # module:function:operator:expression, as keys() names it (no line: lines move)


def _docstring_ids(tree: ast.AST) -> set[int]:
    ids = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                ids.add(id(first))
    return ids


def _inert_ids(tree: ast.AST) -> set[int]:
    """Nodes whose mutation cannot change a result by construction: type annotations (strings
    under ``from __future__ import annotations``), ``strict=True`` of ``zip`` (it only
    checks lengths that are equal) and ``compare=`` and ``repr=`` of a dataclass ``field`` (how
    objects compare and print, never a result), so they are no mutation points."""
    ids: set[int] = set()
    for node in ast.walk(tree):
        notes = []
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            notes.append(node.returns)
            notes += [a.annotation for a in (*node.args.args, *node.args.kwonlyargs, *node.args.posonlyargs)]
            notes += [a.annotation for a in (node.args.vararg, node.args.kwarg) if a is not None]
        elif isinstance(node, ast.AnnAssign):
            notes.append(node.annotation)
        elif isinstance(node, ast.keyword) and node.arg in ("strict", "compare", "repr"):
            notes.append(node.value)
        for n in notes:
            if n is not None:
                ids.update(id(x) for x in ast.walk(n))
    return ids


def _decorator_ids(tree: ast.AST) -> set[int]:
    """The constants of decorators (``@dataclass(frozen=True, slots=True)``): flipping them
    changes how objects are stored, never a result, so they are no mutation points."""
    ids = set()
    for node in ast.walk(tree):
        for dec in getattr(node, "decorator_list", ()):
            ids.update(id(n) for n in ast.walk(dec) if isinstance(n, ast.Constant))
    return ids


def points(tree: ast.AST) -> list[tuple[ast.AST, str, int]]:
    """Every mutation point: (node, operator description, line), in walk order."""
    skip = _docstring_ids(tree) | _decorator_ids(tree) | _inert_ids(tree)
    out: list[tuple[ast.AST, str, int]] = []
    for node in ast.walk(tree):
        line = getattr(node, "lineno", 0)
        if id(node) in skip and not isinstance(node, ast.Expr):
            continue
        if isinstance(node, ast.Compare):
            for i, op in enumerate(node.ops):
                if type(op) in _SWAP_CMP:
                    out.append((node, f"cmp{i}:{type(op).__name__}->{_SWAP_CMP[type(op)].__name__}", line))
        elif isinstance(node, ast.BinOp) and type(node.op) in _SWAP_BIN:
            out.append((node, f"bin:{type(node.op).__name__}->{_SWAP_BIN[type(node.op)].__name__}", line))
        elif isinstance(node, ast.AugAssign) and type(node.op) in _SWAP_BIN:
            out.append((node, f"aug:{type(node.op).__name__}->{_SWAP_BIN[type(node.op)].__name__}", line))
        elif isinstance(node, ast.BoolOp):
            out.append(
                (node, f"bool:{type(node.op).__name__}->{'Or' if isinstance(node.op, ast.And) else 'And'}", line)
            )
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            out.append((node, "not:removed", line))
        elif isinstance(node, ast.If):
            out.append((node, "if:negated", line))
        elif isinstance(node, ast.Constant) and id(node) not in skip:
            v = node.value
            if isinstance(v, bool):
                out.append((node, f"const:{v}->{not v}", line))
            elif isinstance(v, int):
                out.append((node, f"const:{v}->{v + 1}", line))
            elif isinstance(v, float):
                out.append((node, f"const:{v}->{v * 2 if v else 1.0}", line))
        elif isinstance(node, ast.Return) and node.value is not None:
            if not (isinstance(node.value, ast.Constant) and node.value.value is None):
                out.append((node, "return:None", line))
        elif isinstance(node, ast.Expr) and isinstance(node.value, ast.Call) and id(node) not in skip:
            out.append((node, "call:removed", line))
    return out


def _parents(tree: ast.AST) -> dict[int, ast.AST]:
    return {id(child): node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}


def _function(node: ast.AST, parents: dict[int, ast.AST]) -> str:
    """The qualified name of the function (or class) around ``node``, ``<module>`` at the top."""
    names = []
    while id(node) in parents:
        node = parents[id(node)]
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.append(node.name)
    return ".".join(reversed(names)) or "<module>"


def _expression(node: ast.AST, what: str, parents: dict[int, ast.AST]) -> str:
    """The source that names a mutation point: the test of an ``if``, the value of a
    ``return``, a constant with what holds it, the node itself otherwise; one line, at most
    70 characters."""
    kind = what.split(":")[0]
    target: ast.AST = node
    if kind == "if":
        target = node.test  # type: ignore[attr-defined]
    elif kind == "return":
        target = node.value  # type: ignore[attr-defined]
    elif kind == "const" and id(node) in parents:
        target = parents[id(node)]
        if isinstance(target, ast.arguments):  # a parameter's default: name=default
            named = list(zip(reversed(target.posonlyargs + target.args), reversed(target.defaults), strict=False))
            named += list(zip(target.kwonlyargs, target.kw_defaults, strict=True))
            return next(f"{a.arg}={ast.unparse(d)}" for a, d in named if d is node)
        if isinstance(target, ast.keyword):
            target = parents.get(id(target), target)
    text = " ".join(ast.unparse(target).split())
    return text if len(text) <= 70 else text[:67] + "..."


def keys(module: str, tree: ast.AST, pts: list[tuple[ast.AST, str, int]]) -> list[str]:
    """A key per mutation point that survives lines moving: ``module:function:operator:expression``,
    with ``#k`` for the k-th point (k >= 2) of the same function, operator and expression."""
    parents = _parents(tree)
    out: list[str] = []
    seen: dict[str, int] = {}
    for node, what, _ in pts:
        key = f"{module}:{_function(node, parents)}:{what}:{_expression(node, what, parents)}"
        seen[key] = seen.get(key, 0) + 1
        out.append(key if seen[key] == 1 else f"{key}#{seen[key]}")
    return out


def mutate(source: str, index: int) -> tuple[str, str, int]:
    """The source with mutation point ``index`` applied: (new source, what, line)."""
    tree = ast.parse(source)
    node, what, line = points(tree)[index]
    kind = what.split(":")[0]
    if kind.startswith("cmp"):
        i = int(kind[3:])
        node.ops[i] = _SWAP_CMP[type(node.ops[i])]()  # type: ignore[attr-defined]
    elif kind in ("bin", "aug"):
        node.op = _SWAP_BIN[type(node.op)]()  # type: ignore[attr-defined]
    elif kind == "bool":
        node.op = ast.Or() if isinstance(node.op, ast.And) else ast.And()  # type: ignore[attr-defined]
    elif kind == "not":
        _replace(tree, node, node.operand)  # type: ignore[attr-defined]
    elif kind == "if":
        node.test = ast.UnaryOp(ast.Not(), node.test)  # type: ignore[attr-defined]
    elif kind == "const":
        v = node.value  # type: ignore[attr-defined]
        node.value = (not v) if isinstance(v, bool) else v + 1 if isinstance(v, int) else (v * 2 if v else 1.0)  # type: ignore[attr-defined]
    elif kind == "return":
        node.value = ast.Constant(None)  # type: ignore[attr-defined]
    elif kind == "call":
        _replace(tree, node, ast.Pass())
    ast.fix_missing_locations(tree)
    return ast.unparse(tree), what, line


def _replace(tree: ast.AST, old: ast.AST, new: ast.AST) -> None:
    for parent in ast.walk(tree):
        for field, value in ast.iter_fields(parent):
            if value is old:
                setattr(parent, field, new)
                return
            if isinstance(value, list):
                for i, item in enumerate(value):
                    if item is old:
                        value[i] = new
                        return


def _scratch() -> Path:
    """A copy of the repository's tracked files (the tests, specs, grammar and package)."""
    dest = Path(tempfile.mkdtemp(prefix="mitlc-mutation-"))
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    for f in files:
        target = dest / f
        target.parent.mkdir(parents=True, exist_ok=True)
        if (ROOT / f).is_file():
            shutil.copy2(ROOT / f, target)
    return dest


def run_tests(
    copy_root: Path, tests: list[str], timeout: float, log: list[str] | None = None, select: str | None = None
) -> str:
    """``killed`` (a test failed), ``timeout`` (counted as killed) or ``survived``; ``log``
    gets the tests' output."""
    env = {**os.environ, "PYTHONPATH": str(copy_root), "OPENBLAS_NUM_THREADS": "1"}
    cmd = [
        sys.executable,
        "-m",
        "pytest",
        "-x",
        "-q",
        "-p",
        "no:cacheprovider",
        "-n",
        "0",
        *[f"tests/{t}" for t in tests],
        *(["-k", select] if select else []),
    ]
    try:
        r = subprocess.run(cmd, cwd=copy_root, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout"
    if log is not None:
        log.append(r.stdout + r.stderr)
    return "survived" if r.returncode == 0 else "killed"


def rate(counts: dict) -> float:
    """The kill rate: killed / (killed + survived), equivalent mutants left out."""
    return counts["killed"] / max(1, counts["killed"] + counts["survived"])


def table(record: dict) -> str:
    """docs/reliability.md's table of the recorded runs: a row per module, then the commands."""
    rows = [
        "| module | file | points | sampled | killed | equivalent | survived | kill rate |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    commands: dict[str, list[str]] = {}
    for m in sorted(record):
        r = record[m]
        rows.append(
            f"| `{m}` | `{r['file']}` | {r['points']} | {r['sampled']} | {r['killed']} | {r['equivalent']}"
            f" | {r['survived']} | {rate(r):.0%} |"
        )
        commands.setdefault(f"`{r['command']}` ({r['made']})", []).append(f"`{m}`")
    rows.append("")
    for cmd, mods in commands.items():
        rows.append(f"- {', '.join(mods)}: {cmd}")
    left = [f"`{k}`" for m in sorted(record) for k in record[m]["survivors"]]
    if left:
        rows += ["", "Survivors not known to be equivalent (behaviour no test pins down yet): " + ", ".join(left) + "."]
    return "\n".join(rows)


def tally(results: list[tuple[Mutant, str]], module: str) -> dict:
    """One module's outcomes: how many sampled, killed (a timeout counts), equivalent and
    surviving, and the survivors' keys."""
    mine = [(mut, o) for mut, o in results if mut.module == module]
    survivors = sorted(mut.key for mut, o in mine if o == "survived" and mut.key not in EQUIVALENT)
    return {
        "sampled": len(mine),
        "killed": sum(1 for _, o in mine if o in ("killed", "timeout")),
        "equivalent": sum(1 for mut, o in mine if o == "survived" and mut.key in EQUIVALENT),
        "survived": len(survivors),
        "survivors": survivors,
    }


def write_record(results: list[tuple[Mutant, str]], counts: dict[str, int], argv: list[str]) -> None:
    """Merge this run's modules into :data:`RECORD` and rewrite the page's table from it."""
    record = json.loads(RECORD.read_text(encoding="utf-8")) if RECORD.exists() else {}
    made = f"{datetime.date.today().isoformat()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    for m, n_points in counts.items():
        record[m] = {
            "file": TARGETS[m][0],
            "tests": TARGETS[m][1] + ([f"-k {SELECT[m]}"] if m in SELECT else []),
            "points": n_points,
            **tally(results, m),
            "command": " ".join(["python tests/mutation.py", *argv]),
            "made": made,
        }
    write_page(record)


def write_page(record: dict) -> None:
    """Write :data:`RECORD` and the page's table from ``record``, each atomically."""
    text = json.dumps(record, indent=1, sort_keys=True) + "\n"
    page = PAGE.read_text(encoding="utf-8")
    a, b = page.index(TABLE_BEGIN) + len(TABLE_BEGIN), page.index(TABLE_END)
    for path, new in ((RECORD, text), (PAGE, page[:a] + "\n" + table(record) + "\n" + page[b:])):
        tmp = path.with_suffix(".tmp")
        tmp.write_text(new, encoding="utf-8")
        tmp.replace(path)
    print(f"recorded in {RECORD.relative_to(ROOT)} and {PAGE.relative_to(ROOT)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--module", action="append", choices=sorted(TARGETS), help="repeat; default: all")
    ap.add_argument("--sample", type=int, default=45, help="mutants per module (default 45)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds per mutant's tests")
    ap.add_argument("--list", action="store_true", help="print the sampled mutants and stop")
    ap.add_argument("--record", action="store_true", help="write the rows into docs/mutation.json and the page")
    args = ap.parse_args()
    modules = args.module or sorted(TARGETS)
    rng = random.Random(args.seed)
    plan: list[tuple[Mutant, str]] = []
    counts: dict[str, int] = {}
    for m in modules:
        source = (ROOT / TARGETS[m][0]).read_text(encoding="utf-8")
        tree = ast.parse(source)
        pts = points(tree)
        names = keys(m, tree, pts)
        counts[m] = len(pts)
        chosen = sorted(rng.sample(range(len(pts)), min(args.sample, len(pts))))
        for i in chosen:
            new, what, line = mutate(source, i)
            plan.append((Mutant(m, i, line, what, names[i]), new))
        print(f"{m}: {len(pts)} mutation points, {len(chosen)} sampled", flush=True)
    if args.list:
        for mut, _ in plan:
            print(mut.key)
        return
    t0 = time.perf_counter()
    scratches = [_scratch() for _ in range(args.jobs)]
    free = list(scratches)
    import threading

    lock = threading.Lock()
    for s in scratches:  # the unmutated module, printed back by ast, must pass its tests
        for m in modules:
            path, _ = TARGETS[m]
            (s / path).write_text(ast.unparse(ast.parse((ROOT / path).read_text())), encoding="utf-8")
    for m in modules:
        log: list[str] = []
        base = run_tests(scratches[0], TARGETS[m][1], args.timeout, log, SELECT.get(m))
        if base != "survived":
            print("\n".join(log[-1].splitlines()[-40:]) if log else "", flush=True)
            raise SystemExit(f"the tests of {m} fail without any mutant ({base}): fix them first")

    def one(item: tuple[Mutant, str]) -> tuple[Mutant, str]:
        mut, new = item
        with lock:
            s = free.pop()
        path, tests = TARGETS[mut.module]
        original = (s / path).read_text(encoding="utf-8")
        try:
            (s / path).write_text(new, encoding="utf-8")
            outcome = run_tests(s, tests, args.timeout, select=SELECT.get(mut.module))
        finally:
            (s / path).write_text(original, encoding="utf-8")
            with lock:
                free.append(s)
        print(f"{outcome:8} {mut.key}", flush=True)
        return mut, outcome

    with ThreadPoolExecutor(args.jobs) as pool:
        results = list(pool.map(one, plan))
    for s in scratches:
        shutil.rmtree(s, ignore_errors=True)
    print(f"\n{len(results)} mutants in {(time.perf_counter() - t0) / 60:.1f} min (seed {args.seed})")
    print(f"{'module':8} {'killed':>7} {'survived':>9} {'equivalent':>11} {'kill rate':>10}")
    for m in modules:
        t = tally(results, m)
        print(f"{m:8} {t['killed']:7} {t['survived']:9} {t['equivalent']:11} {rate(t):10.0%}")
    survivors = [mut for mut, o in results if o == "survived" and mut.key not in EQUIVALENT]
    if survivors:
        print("\nsurvivors (not known to be equivalent):")
        for mut in survivors:
            line = (ROOT / TARGETS[mut.module][0]).read_text().splitlines()[mut.line - 1].strip()
            print(f"  {mut.key:55} {line[:90]}")
    if args.record:
        write_record(results, counts, sys.argv[1:])


if __name__ == "__main__":
    main()
