"""The package's structure: no import cycles among its modules (an import inside a function
counts too: a cycle hidden in a function is still two modules that cannot be read, tested or
changed apart)."""
import ast
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGES = ("contact_sim", "msg_adapters")


def _module_of(path):
    mod = os.path.relpath(path, ROOT)[:-3].replace(os.sep, ".")
    return mod[:-len(".__init__")] if mod.endswith(".__init__") else mod


def _exists(mod):
    p = os.path.join(ROOT, *mod.split("."))
    return os.path.isdir(p) or os.path.exists(p + ".py")


def import_graph():
    """``{module: set of the package modules it imports}``, every ``import`` and ``from ... import``
    in the module's source, at any depth (a name imported from a package that is itself a module
    is an edge to that module)."""
    graph = {}
    for pkg in PACKAGES:
        for d, _, files in os.walk(os.path.join(ROOT, pkg)):
            for f in files:
                if not f.endswith(".py"):
                    continue
                path = os.path.join(d, f)
                mod = _module_of(path)
                parts = mod.split(".") if f == "__init__.py" else mod.split(".")[:-1]
                edges = graph.setdefault(mod, set())
                with open(path, encoding="utf-8") as fh:
                    tree = ast.parse(fh.read())
                for node in ast.walk(tree):
                    if isinstance(node, ast.ImportFrom):
                        base = parts[:len(parts) - node.level + 1] if node.level else []
                        target = ".".join(base + ([node.module] if node.module else []))
                        for alias in node.names:
                            sub = f"{target}.{alias.name}"
                            edges.add(sub if _exists(sub) else target)
                    elif isinstance(node, ast.Import):
                        edges.update(a.name for a in node.names)
                edges.intersection_update(m for m in edges if m.split(".")[0] in PACKAGES and m != mod)
    return graph


def cycles(graph):
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_graph_sees_imports_at_every_depth():
    g = import_graph()
    assert "contact_sim.collision.pair_kernels" in g["contact_sim.response.toi"]   # inside a function
    assert "contact_sim.response.bounds" in g["contact_sim.response.swept"]


def test_no_import_cycles():
    assert cycles(import_graph()) == []


def test_a_cycle_is_found():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


@pytest.mark.parametrize("pkg", PACKAGES)
def test_every_module_is_in_the_graph(pkg):
    assert any(m.startswith(pkg + ".") for m in import_graph())


def test_the_constants_module_is_the_bottom_of_the_graph_and_says_what_each_constant_is():
    """``contact_sim.constants`` (Box2D's ``constants.h``) imports nothing from the package, and each
    constant comes with a comment saying what it bounds."""
    import re

    assert import_graph()["contact_sim.constants"] == set()
    with open(os.path.join(ROOT, "contact_sim", "constants.py"), encoding="utf-8") as fh:
        lines = [l for l in fh.read().splitlines() if re.match(r"[A-Z_0-9]+ = ", l)]
    assert len(lines) > 30
    assert [l.split(" =")[0] for l in lines if "#" not in l] == []


def test_the_engine_and_the_node_do_not_import_ray():
    """Ray is the optional cluster extra of studies (``contact-sim study --cluster``): importing
    the engine, its studies or the node's conversions must not import it (it is imported only
    inside the Ray executor)."""
    import subprocess
    import sys

    code = ("import sys, contact_sim, contact_sim.study, contact_sim.cli, msg_adapters.conversions; "
            "assert 'ray' not in sys.modules, 'ray was imported'")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                       env=dict(os.environ, PYTHONPATH=ROOT))
    assert r.returncode == 0, r.stderr
