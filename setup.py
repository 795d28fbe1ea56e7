"""contact_sim: an ament_python package (colcon build) that also installs with plain pip."""
import os
from glob import glob

import subprocess
import sys

from setuptools import find_packages, setup
from setuptools.command.install import install

PACKAGE = "contact_sim"


def tree(src, dest):
    """data_files entries for every file under ``src``, keeping the folder layout under ``dest``."""
    out = {}
    for path in glob(os.path.join(src, "**", "*"), recursive=True):
        if os.path.isfile(path):
            out.setdefault(os.path.join(dest, os.path.dirname(path)), []).append(path)
    return sorted(out.items())


class InstallAndCompile(install):
    """``install``, then compile the installed copy's kernels once (numba caches them beside the
    installed source: ``contact_sim.warmup``, then the node's: ``msg_adapters.state_rows``), so the first run after a colcon build does not stall
    on compilation. Best effort; skipped for staged installs (``--root``: wheels, packaging) and
    with ``CONTACT_SIM_NO_WARMUP=1``."""

    def run(self):
        super().run()
        if self.root or os.environ.get("CONTACT_SIM_NO_WARMUP"):
            return
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [self.install_lib] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
        try:
            for module in ("contact_sim.warmup", "msg_adapters.state_rows"):
                subprocess.call([sys.executable, "-m", module], cwd=self.install_lib, env=env, timeout=900)
        except (OSError, subprocess.SubprocessError) as exc:   # never fail an install over a cache
            print(f"contact_sim: kernels not precompiled ({exc}); they compile on first use", file=sys.stderr)


setup(
    name=PACKAGE,
    cmdclass={"install": InstallAndCompile},
    version="0.1.0",
    description="Collision detection and contact response for rigid bodies in Python (numpy, numba), with a ROS 2 node",
    packages=find_packages(include=["contact_sim", "contact_sim.*", "msg_adapters", "msg_adapters.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
    ] + tree("config", "share/" + PACKAGE),
    python_requires=">=3.10",
    # yourdfpy: the URDF parser of World.add_urdf
    install_requires=["numpy>=1.24", "scipy>=1.10", "trimesh>=4.0", "PyYAML>=6.0", "tqdm>=4.60", "numba>=0.60",
                      "yourdfpy>=0.0.56"],
    extras_require={
        # the ROS node needs the ROS 2 Jazzy wheels (requirements/ros.txt) or a sourced ROS install
        "plot": ["matplotlib>=3.6"],
        # contact-sim study --cluster: studies as Ray tasks (imported only then; never by the engine or the node);
        # [client]: --cluster ray://HOST:PORT
        "cluster": ["ray[client]>=2.9"],
        "test": ["pytest>=7", "pytest-timeout>=2.1", "hypothesis>=6.100", "matplotlib>=3.6", "python-fcl>=0.7", "rtree>=1.0"],
        # make docs: the documentation site (mkdocs.yml; docs/)
        "docs": ["mkdocs>=1.6", "mkdocs-material>=9.5", "mkdocstrings[python]>=0.26"],
        "bench": ["matplotlib>=3.6", "python-fcl>=0.7", "pybullet>=3.2", "mujoco>=3.0"],
    },
    zip_safe=True,
    maintainer="contact_sim developers",
    maintainer_email="contact-sim@example.com",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "contact-sim = contact_sim.cli:main",
            "contact_sim_node = msg_adapters.launch:main",
        ],
    },
)
