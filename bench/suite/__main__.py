"""``python -m bench.suite [TASK ...]``: every task's witness from every start of its spread, and zero input's."""

import sys

from bench.suite.tasks import main

sys.exit(main(sys.argv[1:]))
