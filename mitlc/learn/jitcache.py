"""Compiled kernels kept on disk: numba compiles a trial once per machine, not once per process.

numba caches a compiled function next to its source file, which a closure built at run
time (the fused trial over one plant step and one spec's predicates) does not have. So
:func:`load` writes the plain-Python closure graph of a kernel as generated modules, one
per function (:func:`module_sources`): a function reached through a closure cell or a global
is imported from its own module, the numbers it reads become literals there, modules imports,
and every function is compiled by numba with ``cache=True``, in IEEE order (unless the plain
function carries ``__mitlc_jit__``, the options of the fast kernel's leaf functions: fastmath
flags for its sums, no reference counts; :mod:`mitlc.learn.sacpn.simd`). A module's name is the
hash of its text (with numba's and mitlc's versions), and that text names the modules of the
functions it calls, so a kernel is compiled the first time it is needed and loaded from the
cache in every later process (trainings, sweep workers and Ray workers alike), and a new spec's
kernel compiles only the functions that differ from a kernel compiled before: the trial, the
plant's step and the predicates (pendulum/n2_hold_up's kernel 10 s -> 3.6 s after n1_reach_in_time's
on this project's machine); the feature, sum and obligation functions are loaded compiled.

Where: ``$MITLC_CACHE_DIR`` if set (empty: no disk cache), else
``$XDG_CACHE_HOME/mitlc`` or ``~/.cache/mitlc``, in ``kernels/``. The files there are
mitlc's own and safe to delete. Where the folder cannot be written, or a function's
graph holds something that cannot be written as source, :func:`load` returns None and
the caller compiles in memory as before: the same code, the same numbers.

Loading from there runs code: the generated module (and Python's ``.pyc`` of it), and
numba's index and data files, which are pickles. So the cache is used only as far as it is
the user's own (:mod:`mitlc.cachefiles`, as ssh does): the cache root, ``kernels/`` and its
``__pycache__/`` (made ``0700``) owned by the current user and writable by nobody else, and
the kernel's files in them too; otherwise :func:`load` returns None (compiled in memory),
and :func:`announce`'s line says why.

numba compiles a kernel on its first call; :func:`announce`, called just before it, tells
the function set by :func:`set_notice` (the command line's: one line on stderr) when that
call is going to compile rather than load from the cache, so that a first training does
not look hung.
"""

from __future__ import annotations

import ast
import builtins
import hashlib
import importlib.util
import inspect
import math
import os
import sys
import tempfile
import textwrap
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mitlc.cachefiles import cache_folder, untrusted
from mitlc.fileio import cache_root

__all__ = ["cache_dir", "module_source", "module_sources", "load", "set_notice", "will_compile", "announce"]

JIT_OPTIONS = "fastmath=False, error_model='numpy', nogil=True, cache=True"
_LOADED: dict[str, types.ModuleType] = {}
"""The generated modules imported in this process, by module name."""
MODULE_PREFIX = "mitlc_kernel_"
"""A generated module's name: this and the first 24 hex digits of its text's SHA-256 (its file:
``kernel_<digits>.py``)."""
_NOTICE: Callable[[str], None] | None = None
_REFUSED: str | None = None
"""Why the last :func:`load` did not use the disk cache it has (a folder or file not the user's own)."""


class Unwritable(Exception):
    """A value in a kernel's closure graph that cannot be written as module source."""


def cache_dir() -> Path | None:
    """The folder of the generated kernels, or None when the disk cache is off (``MITLC_CACHE_DIR=``)."""
    root = cache_root()
    return root / "kernels" if root is not None else None


def _python_function(value: Any) -> types.FunctionType | None:
    """The plain-Python function behind ``value`` (itself, or a numba dispatcher's ``py_func``)."""
    if isinstance(value, types.FunctionType):
        return value
    py = getattr(value, "py_func", None)
    return py if isinstance(py, types.FunctionType) else None


def _literal(value: Any) -> str | None:
    if isinstance(value, bool) or value is None:
        return repr(value)
    if isinstance(value, int):
        return repr(int(value))
    if isinstance(value, float):
        if math.isfinite(value):
            return repr(float(value))
        return "math.nan" if math.isnan(value) else ("math.inf" if value > 0 else "(-math.inf)")
    return None


def _free_names(fn: ast.FunctionDef) -> tuple[set[str], list[str]]:
    """``(bound, free)``: the names a function body binds, and those it loads without binding
    them, in the order they are read."""
    bound = {a.arg for a in (*fn.args.posonlyargs, *fn.args.args, *fn.args.kwonlyargs)}
    if fn.args.vararg or fn.args.kwarg:
        raise Unwritable(f"{fn.name} takes *args or **kwargs")
    for node in ast.walk(fn):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store | ast.Del):
            bound.add(node.id)
        elif isinstance(node, ast.FunctionDef | ast.Lambda | ast.ClassDef) and node is not fn:
            raise Unwritable(f"{fn.name} defines a function or class inside")
        elif isinstance(node, ast.Global | ast.Nonlocal):
            raise Unwritable(f"{fn.name} declares global or nonlocal names")
    loads = (n.id for n in ast.walk(fn) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Load))
    return bound, list(dict.fromkeys(name for name in loads if name not in bound))


def _options(options: Any) -> str:
    """``numba.njit(...)`` for a function's ``__mitlc_jit__``: :data:`JIT_OPTIONS` with its ``fastmath``
    (a set of LLVM fast-math flag names) and ``_nrt`` (False: no reference counts, for a function
    that allocates nothing) as given."""
    opts = dict(options)
    flags = sorted(str(f) for f in opts.pop("fastmath", ()))
    nrt = opts.pop("_nrt", True)
    if opts or not all(f.isidentifier() for f in flags) or not isinstance(nrt, bool):
        raise Unwritable(f"jit options {options!r}")
    text = JIT_OPTIONS
    if flags:
        text = text.replace("fastmath=False", "fastmath={" + ", ".join(repr(f) for f in flags) + "}")
    if not nrt:
        text += ", _nrt=False"
    return f"numba.njit({text})"


class _Module:
    """The names of one generated module: its function's own, and one per value it reads."""

    def __init__(self) -> None:
        self.taken: set[str] = set()
        self.by_id: dict[int, str] = {}  # id(value) -> its name here
        self.imports: list[str] = []  # "import x as y" and "from kernel import f as g" lines
        self.constants: list[str] = []

    def unique(self, base: str) -> str:
        base = base.strip("_") or "f"
        name, k = base, 1
        while name in self.taken or hasattr(builtins, name) or name in ("math", "np", "numba", "_jit"):
            k += 1
            name = f"{base}_{k}"
        self.taken.add(name)
        return name


class _Writer:
    """Writes a closure graph as modules, one per function: a function's module defines the numbers it
    reads and imports the functions it calls from theirs, and is named by the hash of its text (which
    names its callees' modules, so the hash covers everything the function runs)."""

    def __init__(self, versions: str) -> None:
        self.versions = versions
        self.done: dict[int, tuple[str, str]] = {}  # id(fn) -> (its module, its name there)
        self.busy: set[int] = set()  # the functions being written: reached again, a cycle
        self.modules: dict[str, str] = {}  # module name -> source, each after the modules it imports
        self.keep: list[Any] = []  # the values written, alive while ids are keys

    def value(self, here: _Module, name: str, value: Any) -> str:
        """The name in the module ``here`` that holds ``value``, read there as ``name``."""
        if isinstance(value, types.ModuleType):
            if value.__name__ == "numpy":
                return "np"
            if value.__name__ == "math":
                return "math"
        if id(value) in here.by_id:
            return here.by_id[id(value)]
        if isinstance(value, types.ModuleType):
            alias = here.unique(name)
            here.imports.append(f"import {value.__name__} as {alias}")
        elif (fn := _python_function(value)) is not None:
            module, own = self.function(fn)
            alias = here.unique(name)
            here.imports.append(f"from {module} import {own}" + (f" as {alias}" if alias != own else ""))
        else:
            text = _literal(value)
            if text is None:
                raise Unwritable(f"'{name}' is a {type(value).__name__}, not a number, module or function")
            alias = here.unique(name)
            here.constants.append(f"{alias} = {text}")
        self.keep.append(value)
        here.by_id[id(value)] = alias
        return alias

    def function(self, fn: types.FunctionType) -> tuple[str, str]:
        """``fn``'s module (written, with the modules of the functions it calls) and its name there."""
        if id(fn) in self.done:
            return self.done[id(fn)]
        if id(fn) in self.busy:
            raise Unwritable(f"{fn.__qualname__} calls itself")
        self.busy.add(id(fn))
        source = getattr(fn, "__mitlc_source__", None)
        if source is None:
            try:
                source = textwrap.dedent(inspect.getsource(fn))
            except (OSError, TypeError) as exc:
                raise Unwritable(f"no source for {fn.__qualname__}") from exc
        tree = ast.parse(source)
        node = tree.body[0]
        if not isinstance(node, ast.FunctionDef) or len(tree.body) != 1:
            raise Unwritable(f"{fn.__qualname__} is not one plain function definition")
        if node.decorator_list:
            raise Unwritable(f"{fn.__qualname__} is decorated")
        node.returns = None
        for a in (*node.args.posonlyargs, *node.args.args, *node.args.kwonlyargs):
            a.annotation = None
        if fn.__defaults__ or fn.__kwdefaults__:
            raise Unwritable(f"{fn.__qualname__} has default arguments")
        here = _Module()
        own = here.unique(fn.__name__)
        cells = dict(zip(fn.__code__.co_freevars, [c.cell_contents for c in fn.__closure__ or ()], strict=True))
        local, free_names = _free_names(node)
        renames: dict[str, str] = {}
        for free in free_names:
            if free in cells:
                renames[free] = self.value(here, free, cells[free])
            elif free in fn.__globals__:
                renames[free] = self.value(here, free, fn.__globals__[free])
            elif not hasattr(builtins, free):
                raise Unwritable(f"{fn.__qualname__} reads '{free}', which is not defined")
        if any(new in local and new != old for old, new in renames.items()):
            raise Unwritable(f"{fn.__qualname__}: a local name equals a module-level one")
        for n in ast.walk(node):
            if isinstance(n, ast.Name) and n.id in renames and isinstance(n.ctx, ast.Load):
                n.id = renames[n.id]
        node.name = own
        if isinstance(node.body[0], ast.Expr) and isinstance(getattr(node.body[0], "value", None), ast.Constant):
            node.body = node.body[1:] or [ast.Pass()]  # the docstring
        options = getattr(fn, "__mitlc_jit__", None)  # a fast kernel's leaf functions: their own options
        jit = "_jit" if options is None else _options(options)
        head = [
            f'"""Generated by mitlc from {fn.__module__}.{fn.__qualname__} ({self.versions}); safe to delete."""',
            "",
            "import math",
            "",
            "import numba",
            "import numpy as np",
            *here.imports,
            "",
            f"_jit = numba.njit({JIT_OPTIONS})",
            "",
            *here.constants,
        ]
        text = "\n".join(head) + "\n\n\n" + ast.unparse(node) + f"\n\n\n{own} = {jit}({own})\n"
        module = f"{MODULE_PREFIX}{hashlib.sha256(text.encode()).hexdigest()[:24]}"
        self.modules.setdefault(module, text)
        self.keep.append(fn)
        self.done[id(fn)] = (module, own)
        self.busy.discard(id(fn))
        return module, own


def module_sources(fn: Callable, versions: str) -> tuple[list[tuple[str, str]], str, str]:
    """``(modules, module, name)``: the modules that define ``fn``'s closure graph compiled with
    ``cache=True``, as ``(module name, source)``, each after the modules it imports; the module of
    ``fn`` itself (the last) and ``fn``'s name in it. Raises :class:`Unwritable`."""
    py = _python_function(fn)
    if py is None:
        raise Unwritable(f"{fn!r} is not a Python function")
    w = _Writer(versions)
    module, name = w.function(py)
    return list(w.modules.items()), module, name


def module_source(fn: Callable, versions: str) -> tuple[str, str]:
    """``(source, name)``: :func:`module_sources`'s modules as one text (to read), and ``fn``'s name."""
    modules, _, name = module_sources(fn, versions)
    return "\n\n".join(source for _, source in modules), name


def _versions() -> str:
    import numba

    from mitlc import __version__

    return f"mitlc {__version__}, numba {numba.__version__}, Python {sys.version_info[0]}.{sys.version_info[1]}"


def load(fn: Callable) -> Callable | None:
    """``fn`` (a plain-Python kernel, closures and all) compiled by numba through modules
    in the disk cache; None where there is no cache or ``fn`` cannot be written as source."""
    global _REFUSED
    if cache_dir() is None:
        return None
    try:
        modules, top, name = module_sources(fn, _versions())
    except Unwritable:
        return None
    if top not in _LOADED:
        pycache, why = cache_folder("kernels", "__pycache__")  # numba's files and the .pyc go there
        if pycache is None:
            _REFUSED = why
            return None
        for module, source in modules:  # a module's imports are loaded before it
            if module not in _LOADED and not _load_module(module, source, pycache):
                return None
    return getattr(_LOADED[top], name)


def _load_module(module: str, source: str, pycache: Path) -> bool:
    """The generated module ``module`` written (once) and imported from the kernels folder, where its
    files are the user's own and its text is ``source``; False otherwise."""
    global _REFUSED
    digest = module.removeprefix(MODULE_PREFIX)
    folder = pycache.parent
    path = folder / f"kernel_{digest}.py"
    try:
        if not path.exists():
            fd, tmp = tempfile.mkstemp(dir=folder, prefix=".kernel-", suffix=".tmp")
            try:
                with os.fdopen(fd, "w") as fh:
                    fh.write(source)
                try:
                    os.link(tmp, path)  # atomic; another process's equal file wins
                except FileExistsError:
                    pass
            finally:
                os.unlink(tmp)
        why = _untrusted_files(path, pycache, digest)
        if why is not None:
            _REFUSED = why
            return False
        if path.read_text() != source:  # a damaged file: not ours to trust
            return False
    except OSError:
        return False
    _REFUSED = None
    spec = importlib.util.spec_from_file_location(module, path)
    assert spec is not None and spec.loader is not None
    loaded = importlib.util.module_from_spec(spec)
    sys.modules[module] = loaded  # numba's cache finds a function's globals by module name; importers find it
    spec.loader.exec_module(loaded)
    _LOADED[module] = loaded
    return True


def _untrusted_files(path: Path, pycache: Path, digest: str) -> str | None:
    """Why the kernel module ``path`` or a file of it in ``pycache`` (its ``.pyc``, numba's index and
    data) is not to be loaded, or None."""
    files = [path, *sorted(pycache.glob(f"kernel_{digest}.*"))]
    for f in files:
        problem = untrusted(f)
        if problem is not None:
            return f"{f} is {problem}"
    return None


# ---------------------------------------------------------------- telling a compile apart from a load


def set_notice(callback: Callable[[str], None] | None) -> Callable[[str], None] | None:
    """Have ``callback(line)`` told when a kernel is about to be compiled (:func:`announce`),
    None: nobody (the default). Returns the callback set before."""
    global _NOTICE
    before, _NOTICE = _NOTICE, callback
    return before


def will_compile(fn: Any) -> bool:
    """Whether calling ``fn`` compiles it: a numba dispatcher with no compiled signature in
    this process and, where it is cached on disk, no index file there yet. False for
    anything else (a plain-Python kernel)."""
    signatures = getattr(fn, "signatures", None)
    if signatures is None or signatures:
        return False
    index = getattr(getattr(getattr(fn, "_cache", None), "_cache_file", None), "_index_path", None)
    return not (isinstance(index, str) and os.path.exists(index))


def _home(path: Path) -> str:
    try:
        return str(Path("~") / path.relative_to(Path.home()))
    except (ValueError, RuntimeError):
        return str(path)


def announce(fn: Any) -> None:
    """Tell the :func:`set_notice` callback, if any, that the next call of ``fn`` compiles it."""
    if _NOTICE is None or not will_compile(fn):
        return
    index = getattr(getattr(getattr(fn, "_cache", None), "_cache_file", None), "_index_path", None)
    folder = cache_dir()
    if isinstance(index, str) and folder is not None:
        where = f"once per plant and propositions: cached in {_home(folder)}"
    elif folder is None:
        where = "in every process: MITLC_CACHE_DIR is empty, the disk cache is off"
    elif _REFUSED is not None:
        where = f"in every process: the disk cache is not used, {_REFUSED}"
    else:
        where = "in every process: this kernel cannot be cached on disk"
    _NOTICE(f"compiling the training kernel (up to ~10 s, {where})")
