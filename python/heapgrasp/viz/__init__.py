"""See what a run did: each phase recorded with rerun-sdk (``heapgrasp show``,
``heapgrasp run --viz``), written to a ``.rrd`` file for the Rerun viewer."""
