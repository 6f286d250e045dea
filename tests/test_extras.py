"""Optional features are extras (pyproject.toml, README.md): a missing
package gives one line naming its extra, and the dev extra installs every
extra's packages (the tests need them all)."""

import shutil
import sys
import tomllib
from pathlib import Path

import pytest

from bridge.serial import deploy
from sim_backend import sweep

ROOT = Path(__file__).resolve().parents[1]


def test_the_dev_extra_holds_every_other_extra_and_the_readme_names_them():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]
    dev = set(extras.pop("dev"))
    readme = (ROOT / "README.md").read_text()
    assert set(extras) >= {"deploy", "dask", "parquet", "notebook"}
    for name, reqs in extras.items():
        assert set(reqs) <= dev, name
        assert f"pip install 'touchswarm[{name}]'" in readme, name


def test_a_dask_executor_without_dask_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)     # import fails
    with pytest.raises(ValueError, match=r"pip install 'touchswarm\[dask\]'"):
        sweep.executor_from_spec("dask://127.0.0.1:8786")


def test_deploy_without_its_tools_names_the_extra(monkeypatch, tmp_path):
    monkeypatch.setattr(sys, "executable", str(tmp_path / "python"))
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(deploy.DeployError, match=r"mpremote not found: pip install "
                                                 r"'touchswarm\[deploy\]'"):
        deploy._tool("mpremote", None)
