"""MkDocs hooks: the pages generated from the code at build time, so they cannot drift from it.

- ``<!-- parameters -->`` (docs/ros.md) becomes the node's parameter table, read from
  ``msg_adapters.config.PARAMETERS`` (default, type, range, read-only, description).
- ``<!-- api -->`` (docs/api.md) becomes one mkdocstrings block per name in ``contact_sim.__all__``.
- The benchmark charts live in ``bench/results/`` (where ``make bench`` writes them); the pages link
  them as ``../bench/results/NAME.png`` (right when the Markdown is read in the repository), and the
  site serves them as ``bench-results/NAME.png``.

A page that should hold a marker and does not fails the build (``on_post_build``).
"""
import glob
import os
import sys

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

MARKERS = {"ros.md": "<!-- parameters -->", "api.md": "<!-- api -->"}
_replaced = set()


def _cell(text):
    return str(text).replace("|", "\\|").replace("\n", " ")


def parameter_table():
    """The node's parameters as a Markdown table, from ``msg_adapters.config.PARAMETERS``."""
    from rclpy.parameter import Parameter

    from msg_adapters.config import PARAMETERS

    rows = ["| parameter | default | type | range | read-only | description |", "|---|---|---|---|---|---|"]
    for name, (default, desc) in PARAMETERS.items():
        if isinstance(default, Parameter.Type):      # declared by type only: unset by default
            kind = {Parameter.Type.STRING_ARRAY: "string[]", Parameter.Type.DOUBLE_ARRAY: "double[]"}.get(
                default, default.name.lower())
            shown = "unset"
        else:
            kind = {bool: "bool", int: "integer", float: "double", str: "string"}[type(default)]
            if kind == "double" and desc.dynamic_typing:
                kind = "double (an integer is accepted)"
            shown = f"`{default!r}`" if isinstance(default, str) else f"`{str(default).lower() if isinstance(default, bool) else default}`"
        if desc.floating_point_range:
            r = desc.floating_point_range[0]
            span = f"{r.from_value:g} to {r.to_value:g}"
        elif desc.integer_range:
            r = desc.integer_range[0]
            span = f"{r.from_value} to {r.to_value}"
        elif desc.additional_constraints:
            span = ", ".join(f"`{x.strip()}`" for x in desc.additional_constraints.split("|"))
        else:
            span = ""
        rows.append(f"| `{name}` | {_cell(shown)} | {kind} | {_cell(span)} | {'yes' if desc.read_only else ''} | "
                    f"{_cell(desc.description)} |")
    return "\n".join(rows)


def api_blocks():
    """One mkdocstrings block per public name of ``contact_sim`` (``__all__``), in that order."""
    import contact_sim

    return "\n\n".join(f"::: contact_sim.{name}" for name in contact_sim.__all__)


def on_files(files, config):
    for path in sorted(glob.glob(os.path.join(ROOT, "bench", "results", "*.png"))):
        files.append(File.generated(config, "bench-results/" + os.path.basename(path), abs_src_path=path))
    return files


def on_page_markdown(markdown, page, config, files):
    name = page.file.src_uri
    marker = MARKERS.get(name)
    if marker and marker in markdown:
        markdown = markdown.replace(marker, parameter_table() if name == "ros.md" else api_blocks())
        _replaced.add(name)
    return markdown.replace("](../bench/results/", "](bench-results/")


def on_post_build(config):
    missing = sorted(set(MARKERS) - _replaced)
    if missing:
        raise PluginError(f"generated content not placed: {', '.join(f'{m} lacks {MARKERS[m]}' for m in missing)}")
