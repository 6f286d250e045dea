"""Settings for the whole suite (tests/ and hil_tests/).

The soa engine is compiled without numba's forceinline here
(TOUCHSWARM_SOA_INLINE=0, inherited by the CLI subprocesses the tests start):
the same generated functions with the same results, half the cold compile
(the thesis step about 75 s instead of 150 s on this 2-core machine), so a
clean clone's `make test` stays under ten minutes. The inlined build is the
CLI's default and what bench/engine_speed.py measures; the generated text of
both is checked in tests/test_soa_engine.py. A variable set by the caller wins.
"""

import os

os.environ.setdefault("TOUCHSWARM_SOA_INLINE", "0")


# Every command in README and the guide is run by a test (tests/doc_commands.py):
# the CLI records each command line the suite runs, and after the whole suite
# the documented ones it never ran successfully fail the session by name.
def pytest_configure(config) -> None:
    if "TOUCHSWARM_ARGV_LOG" not in os.environ and not hasattr(config, "workerinput"):
        import tempfile
        fd, path = tempfile.mkstemp(prefix="touchswarm-argv-", suffix=".jsonl")
        os.close(fd)
        os.environ["TOUCHSWARM_ARGV_LOG"] = path
        config._touchswarm_argv_log = path


def _whole_suite(config) -> bool:
    from _pytest.config import Config
    opt = config.option
    return (config.args_source == Config.ArgsSource.TESTPATHS and not opt.keyword
            and not opt.markexpr and not getattr(opt, "lf", False)
            and not getattr(opt, "deselect", None) and not opt.maxfail)


def pytest_sessionfinish(session, exitstatus) -> None:
    path = getattr(session.config, "_touchswarm_argv_log", None)
    if path is None:
        return
    try:
        if _whole_suite(session.config) and session.testscollected:
            from pathlib import Path
            from tests import doc_commands
            missing = doc_commands.uncovered(Path(path))
            if missing:
                tr = session.config.pluginmanager.get_plugin("terminalreporter")
                tr.write_line(f"documented commands no test ran ({len(missing)}; "
                              "tests/doc_commands.py):", red=True)
                for m in missing:
                    tr.write_line(f"  {m}", red=True)
                tr.write_line(f"(the command lines the suite ran: {path})", red=True)
                session.exitstatus = 1
                return
    except Exception as err:             # the check must never hide the results
        print(f"conftest: the documented-commands check failed: {err!r}")
        session.exitstatus = 1
        return
    os.unlink(path)
