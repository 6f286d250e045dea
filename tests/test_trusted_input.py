"""Data files name, never import: a scenario TOML, a
recording's sidecar and a journal's meta may name only installed
behaviours; a folder they name is refused in one line, before its code
runs, unless the user names the same folder on the command line
(`--behaviour DIR` or `--trust-behaviour DIR`)."""

from __future__ import annotations

import json
import shutil

from bridge.cli import main
from bridge.host.journal import Journal
from sim_backend import registry

RUN = ["--robots", "6", "--set", "maxTicks=30", "--seed", "1"]


def evil(tmp_path):
    """A copy of aggregate whose __init__.py leaves a mark when imported."""
    folder = tmp_path / "evil"
    shutil.copytree(registry.load("aggregate").folder, folder,
                    ignore=shutil.ignore_patterns("__pycache__"))
    mark = tmp_path / "RAN"
    init = folder / "__init__.py"
    init.write_text(f"open({str(mark)!r}, 'w').close()\n" + init.read_text())
    return folder, mark


def one_line(capsys, *needles) -> None:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    for n in needles:
        assert n in err, err


def test_a_scenario_file_naming_a_folder_runs_no_code(tmp_path, capsys) -> None:
    folder, mark = evil(tmp_path)
    toml = tmp_path / "s.toml"
    toml.write_text(f'behaviour = "{folder}"\n')
    assert main(["run", "--scenario", str(toml), *RUN]) == 2
    one_line(capsys, "names the behaviour folder", "--trust-behaviour")
    assert not mark.exists()
    # the user vouches for it: it runs
    assert main(["run", "--scenario", str(toml), *RUN, "--trust-behaviour", str(folder),
                 "--json"]) in (0, 1)
    assert mark.exists()
    mark.unlink()
    assert main(["run", "--scenario", str(toml), *RUN, "--behaviour", str(folder),
                 "--json"]) in (0, 1)
    capsys.readouterr()
    # trust lasts one command line
    assert main(["run", "--scenario", str(toml), *RUN]) == 2


def test_a_sidecar_naming_a_folder_runs_no_code(tmp_path, capsys) -> None:
    folder, mark = evil(tmp_path)
    rec = tmp_path / "r.blf"
    assert main(["run", *RUN, "--behaviour", str(folder), "--link", "can", "--record",
                 str(rec), "--json"]) in (0, 1)
    mark.unlink()
    capsys.readouterr()
    assert main(["replay", str(rec)]) == 2
    one_line(capsys, "sidecar", "names the behaviour folder")
    assert not mark.exists()
    assert main(["replay", str(rec), "--trust-behaviour", str(folder), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["divergences"] == 0


def test_a_journal_naming_a_folder_runs_no_code_in_view(tmp_path, capsys) -> None:
    folder, mark = evil(tmp_path)
    jp = tmp_path / "j.sqlite"
    with Journal(jp) as j:
        j.bind(str(folder))
    assert main(["view", "--journal", str(jp), "--screenshot", str(tmp_path / "v.png")]) == 2
    one_line(capsys, "its meta names the behaviour folder")
    assert not mark.exists()


def test_the_commands_in_docs_security_run_as_written(tmp_path, capsys, monkeypatch) -> None:
    """docs/security.md's examples, with its placeholders made real."""
    import re
    import shlex
    from pathlib import Path
    folder, mark = evil(tmp_path)
    monkeypatch.chdir(tmp_path)
    Path("s.toml").write_text(f'behaviour = "{folder}"\n')
    assert main(["run", *RUN, "--behaviour", str(folder), "--link", "can", "--record",
                 "r.blf", "--json"]) in (0, 1)
    doc = (Path(__file__).resolve().parents[1] / "docs" / "security.md").read_text()
    block = re.search(r"```sh\n(.*?)```", doc, re.S).group(1)
    lines = [ln.split("#")[0].strip() for ln in block.splitlines() if ln.strip()]
    assert len(lines) == 4
    for line in lines:
        argv = shlex.split(line.replace("/path/evil", str(folder)))[1:]
        trusted = "--trust-behaviour" in argv
        rc = main(argv)
        assert rc in ((0, 1) if trusted else (2,)), (line, capsys.readouterr().err)
    capsys.readouterr()
