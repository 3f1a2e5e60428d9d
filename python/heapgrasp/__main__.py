"""``python -m heapgrasp``: the same command line as the ``heapgrasp`` script."""

from heapgrasp.cli import main

raise SystemExit(main())
