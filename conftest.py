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
