"""The documentation's contracts that a test can hold without building the site (``make docs``
builds it strictly): every public name has a docstring, the benchmark results live in
docs/benchmarks.md as bench/report.py writes them, and every page is in the site's navigation."""
import ast
import importlib.util
import os
import re

import yaml

import contact_sim

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _sources():
    """name -> (module file, name in that module) for every name contact_sim/__init__.py imports."""
    pkg = os.path.join(REPO, "contact_sim")
    with open(os.path.join(pkg, "__init__.py")) as fh:
        tree = ast.parse(fh.read())
    out = {}
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            base = os.path.join(pkg, *node.module.split("."))
            path = base + ".py" if os.path.isfile(base + ".py") else os.path.join(base, "__init__.py")
            for a in node.names:
                out[a.asname or a.name] = (path, a.name)
    return out


def _docstring(path, name, seen=()):
    """The docstring of the top-level class, function or assignment ``name`` in ``path`` (following
    one re-export: ``from .x import name``); an assignment's docstring is the string right after it."""
    with open(path) as fh:
        body = ast.parse(fh.read()).body
    for i, node in enumerate(body):
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)) and node.name == name:
            return ast.get_docstring(node)
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if any(isinstance(t, ast.Name) and t.id == name for t in targets):
                nxt = body[i + 1] if i + 1 < len(body) else None
                if isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant) and isinstance(nxt.value.value, str):
                    return nxt.value.value
                return None
        if isinstance(node, ast.ImportFrom) and node.level == 1 and any(a.name == name for a in node.names):
            base = os.path.join(os.path.dirname(path), *node.module.split("."))
            nested = base + ".py" if os.path.isfile(base + ".py") else os.path.join(base, "__init__.py")
            if nested not in seen:
                return _docstring(nested, name, seen + (path,))
    raise AssertionError(f"{name} is not defined in {path}")


def test_every_public_name_has_a_docstring():
    """The API reference is generated from these docstrings (docs/api.md): each name in
    ``contact_sim.__all__`` must say what it is, in its own source (not inherited, not the
    signature a dataclass makes up)."""
    sources = _sources()
    missing = []
    for name in contact_sim.__all__:
        assert name in sources, f"{name} is in __all__ but not imported by contact_sim/__init__.py"
        doc = _docstring(*sources[name])
        if not doc or len(doc.split()) < 3:
            missing.append(f"{name} ({os.path.relpath(sources[name][0], REPO)})")
    assert not missing, "public names without a docstring: " + ", ".join(missing)


def _report():
    spec = importlib.util.spec_from_file_location("bench_report", os.path.join(REPO, "bench", "report.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_results_block_is_in_docs_benchmarks_as_report_writes_it(tmp_path):
    report = _report()
    assert os.path.samefile(os.path.dirname(report.PAGE), os.path.join(REPO, "docs"))
    with open(report.PAGE) as fh:
        page = fh.read()
    begin, end = page.index(report.BEGIN), page.index(report.END) + len(report.END)
    assert page[begin:end] == report.block()      # what `make bench` would write from bench/results/
    with open(os.path.join(REPO, "README.md")) as fh:
        assert report.BEGIN not in fh.read()      # the README keeps a short headline table only
    # the charts it links exist where the page links them from (docs/ → ../bench/results/)
    for link in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", page[begin:end]):
        assert link.startswith(report.CHARTS)
        assert os.path.isfile(os.path.normpath(os.path.join(REPO, "docs", link))), link

    # main() rewrites the block between the markers and leaves the rest of the page alone
    copy = tmp_path / "benchmarks.md"
    copy.write_text(page.replace(page[begin:end], f"{report.BEGIN}\nstale\n{report.END}"))
    report.PAGE = str(copy)
    report.main()
    assert copy.read_text() == page


def test_every_docs_page_is_in_the_navigation():
    with open(os.path.join(REPO, "mkdocs.yml")) as fh:
        cfg = yaml.safe_load(fh)
    nav = {list(item.values())[0] for item in cfg["nav"]}
    pages = {p for p in os.listdir(os.path.join(REPO, "docs")) if p.endswith(".md")}
    assert pages == nav
