"""Architecture: the package is laid out by the flow of data, its import graph runs one way
(no module imports a later stage, no cycles), and only the store touches HDF5.

Every module under ``antisync/`` is parsed with :mod:`ast` (nothing is imported). Every
``import`` that can run counts, at any level: module level, inside functions, under
``if``/``try``; only the body of ``if TYPE_CHECKING:`` is left out (it never runs: names for
annotations only). Relative imports are resolved. ``from P import name`` is an edge to
``P.name`` when that is a module, else to ``P``. Importing ``a.b.c`` from outside package
``a.b`` also runs ``a/b/__init__.py``, so it is an edge to ``a.b`` too (not to ``a``, the
root every module is inside).
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "antisync"
#: the only package whose modules may import h5py (bench/ and tests/ may too)
HDF5_OWNER = "antisync.store"
#: the stages in the order data flows through them: a module may import its own stage and
#: the stages before it, never one after it ("ground" is the package root's shared files)
STAGES = (
    "ground",
    "physics",
    "laws",
    "stats",
    "kernels",
    "plan",
    "measures",
    "store",
    "execution",
    "sweeps",
    "grids",
    "optimize",
    "report",
    "paper",
    "api",
    "cli",
)
#: the modules at the package root: plumbing and the shared vocabulary (the face is api/ and cli/)
ROOT_MODULES = {
    "antisync",
    "antisync.__main__",
    "antisync._numba_cache",
    "antisync._numba_compile",
    "antisync._version",
    "antisync.errors",
    "antisync.status",
    "antisync.types",
    "antisync.validation",
}


def _modules() -> dict[str, Path]:
    """``{dotted name: file}`` of every module of the package (``__init__`` as the package)."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def _imports(name: str, path: Path) -> list[str]:
    """Every module name ``name`` imports (absolute; relative imports resolved)."""
    is_package = path.name == "__init__.py"
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out = []
    for node in _runtime_nodes(tree):
        if isinstance(node, ast.Import):
            out.extend(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                # a package's own name is its level-1 base; a module's level-1 base is its package
                drop = node.level - 1 if is_package else node.level
                base = base[: len(base) - drop] if drop else base
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module
            # base.name: a submodule, or (resolved below to base) a name defined in base
            out.extend(f"{base}.{alias.name}" for alias in node.names)
    return out


def _runtime_nodes(tree: ast.AST):
    """Every node of ``tree`` except those inside the body of ``if TYPE_CHECKING:``."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            todo.extend(node.orelse)
            continue
        todo.extend(ast.iter_child_nodes(node))


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def import_graph() -> dict[str, set[str]]:
    """``{module: modules it imports}`` within ``antisync``."""
    modules = _modules()
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for name, path in modules.items():
        for target in _imports(name, path):
            # the longest prefix that is a module of ours: a.b.c.func -> a.b.c
            parts = target.split(".")
            while parts and ".".join(parts) not in modules:
                parts.pop()
            if not parts:
                continue  # not ours
            hit = ".".join(parts)
            edges = {hit}
            # importing a.b.c runs a/b/__init__.py first, unless we are inside a.b already
            for k in range(1, len(parts)):
                pkg = ".".join(parts[:k])
                if pkg != "antisync" and not (name == pkg or name.startswith(pkg + ".")):
                    edges.add(pkg)
            graph[name] |= edges - {name}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as ``[a, b, ..., a]``, or None."""
    state: dict[str, int] = {}  # 1: on the stack, 2: done
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_import_graph_has_no_cycles():
    graph = import_graph()
    assert len(graph) > 20 and "antisync.execution.runner" in graph["antisync.cli.run"]  # the walk works
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def stage(module: str) -> str:
    """The stage ``module`` belongs to: its folder, ``api``/``cli`` for the face, else ground."""
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in STAGES:
        return parts[1]
    return "cli" if module == "antisync.__main__" else "ground"


def test_the_root_holds_only_the_face_and_the_ground():
    modules = _modules()
    at_root = {m for m in modules if m.count(".") <= 1 and not (PACKAGE / m.split(".")[-1]).is_dir()}
    assert at_root == ROOT_MODULES, (
        f"modules at the root that belong in a stage: {sorted(at_root - ROOT_MODULES)}"
    )
    folders = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()}
    assert folders == set(STAGES) - {"ground"}, sorted(folders)


def test_no_module_imports_a_later_stage():
    graph = import_graph()
    late = [
        f"{m} ({stage(m)}) imports {t} ({stage(t)})"
        for m in sorted(graph)
        for t in sorted(graph[m])
        if STAGES.index(stage(t)) > STAGES.index(stage(m))
    ]
    assert not late, "imports that run against the flow: " + "; ".join(late)


def test_the_stage_check_sees_a_late_import():
    assert stage("antisync.physics.graphs") == "physics" and stage("antisync.errors") == "ground"
    assert stage("antisync.api") == "api" and stage("antisync.cli.run") == "cli"
    assert STAGES.index(stage("antisync.store.state")) < STAGES.index(stage("antisync.execution.compute"))


def test_only_the_store_imports_h5py():
    offenders = []
    for name, path in _modules().items():
        if name == HDF5_OWNER or name.startswith(HDF5_OWNER + "."):
            continue
        if any(t.split(".")[0] == "h5py" for t in _imports(name, path)):
            offenders.append(name)
    assert not offenders, f"h5py imported outside {HDF5_OWNER}: {', '.join(offenders)}"


def test_summaries_are_pure():
    """summary.py and the sweep analysis turn decoded jobs into records: no file, no store."""
    graph = import_graph()
    for name in ("antisync.stats.summary", "antisync.sweeps.analysis"):
        assert name in graph, name
        reach, todo = set(), [name]
        while todo:
            for nxt in graph[todo.pop()] - reach:
                reach.add(nxt)
                todo.append(nxt)
        assert not {m for m in reach if m == HDF5_OWNER or m.startswith(HDF5_OWNER + ".")}, name


def test_the_walk_counts_local_imports_and_skips_type_checking(tmp_path):
    src = (
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    import antisync.hidden\nelse:\n    import antisync.shown\n"
        "def f():\n    from . import local\n    from .sub import name\n"
    )
    path = tmp_path / "m.py"
    path.write_text(src)
    got = set(_imports("antisync.pkg.m", path))
    assert {"antisync.shown", "antisync.pkg.local", "antisync.pkg.sub.name"} <= got
    assert not any("hidden" in t for t in got)


def test_the_cycle_finder_finds_cycles():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


@functools.cache  # a module imported from in many files is parsed once
def _top_names(path: Path) -> frozenset[str]:
    """The names a module defines at its top level (defs, classes, assignments, imports)."""
    names = set()
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        nodes = [node]
        if isinstance(node, ast.If | ast.Try):  # `try: import x` and `if ...:` at the top level
            nodes = [n for block in (node.body, node.orelse) for n in block]
            nodes += [n for h in getattr(node, "handlers", []) for n in h.body]
        for n in nodes:
            if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                names.add(n.name)
            elif isinstance(n, ast.Assign):
                names |= {t.id for t in n.targets if isinstance(t, ast.Name)}
            elif isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name):
                names.add(n.target.id)
            elif isinstance(n, ast.Import | ast.ImportFrom):
                names |= {(a.asname or a.name).split(".")[0] for a in n.names}
    return frozenset(names)


def test_every_name_imported_from_antisync_exists():
    """``from antisync.x import name`` (at any level, in functions too): ``antisync.x.name`` is a
    module, or ``antisync.x`` defines ``name``. A file move that missed an import is caught here,
    before a user's command reaches the function that holds it."""
    modules = _modules()
    missing = []
    for name, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (
                not isinstance(node, ast.ImportFrom)
                or node.level
                or not (node.module or "").startswith("antisync")
            ):
                continue
            if node.module not in modules:
                missing.append(f"{name}: no module {node.module}")
                continue
            defined = _top_names(modules[node.module])
            for alias in node.names:
                if f"{node.module}.{alias.name}" not in modules and alias.name not in defined:
                    missing.append(f"{name}: {node.module} has no {alias.name}")
    assert not missing, "; ".join(missing)


#: the most arguments a function takes (arrays that travel together go as one group)
MAX_ARGUMENTS = 15


def _argument_counts():
    """``(qualified name, arguments counted)`` of every function in the package: a helper's
    every argument; a public module-level function's positional ones only (its keyword-only
    options are its documented face, as ``scipy.integrate.solve_ivp``'s are); a command of
    ``cli/`` not at all (Typer makes each option an argument)."""
    for name, path in _modules().items():
        if name.startswith("antisync.cli"):
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        public = {n for n in tree.body if isinstance(n, ast.FunctionDef) and not n.name.startswith("_")}
        for node in ast.walk(tree):
            if not isinstance(node, ast.FunctionDef):
                continue
            a = node.args
            count = len(a.posonlyargs) + len(a.args) + (a.vararg is not None)
            if node not in public:
                count += len(a.kwonlyargs) + (a.kwarg is not None)
            yield f"{name}.{node.name}", count


def test_no_function_takes_more_than_fifteen_arguments():
    """The arrays a kernel needs travel as a few named groups (the equations' constants, a
    batch's outputs), not as long positional lists."""
    long = [f"{name} ({count})" for name, count in _argument_counts() if count > MAX_ARGUMENTS]
    assert not long, "more than 15 arguments: " + ", ".join(long)


def _is_parallel(func: ast.FunctionDef) -> bool:
    """``func`` is compiled with ``parallel=True`` (``@njit(parallel=True, ...)``)."""
    return any(
        isinstance(d, ast.Call)
        and any(k.arg == "parallel" and getattr(k.value, "value", None) is True for k in d.keywords)
        for d in func.decorator_list
    )


#: the groups a parallel kernel may unpack in one line: its inputs, which it only reads
READ_ONLY_GROUPS = {"graph", "run", "model", "tangents", "deriv", "tols", "trips"}


def _unpacked(node: ast.Assign) -> str | None:
    """The group ``node`` unpacks (``a, b = group`` or ``a, b = group[:2]``), else None."""
    if not isinstance(node.targets[0], ast.Tuple):
        return None
    value = node.value.value if isinstance(node.value, ast.Subscript) else node.value
    return value.id if isinstance(value, ast.Name) else None


def _unpacking_faults(tree: ast.AST, where: str) -> list[str]:
    """What :func:`test_no_parallel_kernel_writes_through_an_unpacked_tuple` refuses in ``tree``."""
    found = []
    for func in ast.walk(tree):
        if not (isinstance(func, ast.FunctionDef) and _is_parallel(func)):
            continue
        unpacked = set()
        for node in ast.walk(func):
            group = _unpacked(node) if isinstance(node, ast.Assign) else None
            if group is None:
                continue
            if group not in READ_ONLY_GROUPS:
                found.append(f"{where}.{func.name} line {node.lineno} unpacks {group}")
            unpacked |= {e.id for e in node.targets[0].elts if isinstance(e, ast.Name)}
        for node in ast.walk(func):
            targets = node.targets if isinstance(node, ast.Assign) else []
            targets = [node.target] if isinstance(node, ast.AugAssign) else targets
            for target in targets:
                if isinstance(target, ast.Subscript) and getattr(target.value, "id", None) in unpacked:
                    found.append(f"{where}.{func.name} line {node.lineno} writes {target.value.id}")
    return found


def test_no_parallel_kernel_writes_through_an_unpacked_tuple():
    """A ``prange`` loop loses its writes to arrays bound by unpacking a tuple (``a, b = out``
    before the loop: numba 0.68 compiled it, ran it, and left ``a`` and ``b`` untouched; the
    same arrays bound as ``a = out[0]`` or ``a = out.a`` are written; reads are unaffected). A
    parallel kernel unpacks only its read-only input groups (:data:`READ_ONLY_GROUPS`), never
    stores into what it unpacked, and binds its outputs' fields one by one."""
    found = []
    for name, path in _modules().items():
        found += _unpacking_faults(ast.parse(path.read_text(encoding="utf-8")), name)
    assert not found, "; ".join(found)


def test_the_unpacking_check_sees_a_lost_write():
    """The check refuses the two shapes that lost writes (an output group unpacked, a store into
    an unpacked input) and passes the ones that keep them."""
    bad = """
@njit(parallel=True, cache=True)
def f(ks, graph, out):
    status0, steps0 = out
    indptr, indices = graph
    for r in prange(ks.shape[0]):
        status0[r] = 1
        indptr[r] += 1
"""
    good = """
@njit(parallel=True, cache=True)
def f(ks, graph, out):
    status0 = out.status0
    indptr, indices = graph
    for r in prange(ks.shape[0]):
        st, k = step(indptr, indices)
        status0[r] = st
"""
    found = _unpacking_faults(ast.parse(bad), "m")
    assert found == ["m.f line 4 unpacks out", "m.f line 7 writes status0", "m.f line 8 writes indptr"]
    assert not _unpacking_faults(ast.parse(good), "m")


def test_the_job_builder_reads_the_estimators_declarations_not_their_names():
    """Each ``lambda.method`` declares the rows it needs once (``antisync.types.LAMBDA_ROWS``);
    ``plan/jobs.py`` builds a job from the declarations and holds no method's name, and every
    estimator of the dispatch table is declared."""
    from antisync.execution.dispatch import PASSES
    from antisync.types import LAMBDA_METHODS, LAMBDA_ROWS

    assert set(LAMBDA_ROWS) == set(LAMBDA_METHODS)
    assert {method for _, method in PASSES} <= set(LAMBDA_ROWS)
    tree = ast.parse((PACKAGE / "plan" / "jobs.py").read_text(encoding="utf-8"))
    strings = {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)}
    assert not strings & set(LAMBDA_METHODS), sorted(strings & set(LAMBDA_METHODS))
