"""What runs leave behind, read and written the same way by every command.

* :mod:`~heapgrasp.results.records` — the run directory (:class:`~heapgrasp.results.records.RunDir`:
  ``config.json``, resumable ``scenes.jsonl``, a lock, ``results.json``) and atomic JSON
  writes;
* :mod:`~heapgrasp.results.summary` — a run's summary (§VI-D metrics per scene group,
  the leftover analysis) and its one-line method label;
* :mod:`~heapgrasp.results.stats` — Wilson intervals, paired scene-bootstrap differences;
* :mod:`~heapgrasp.results.pages` — a benchmark folder's ``summary.md`` (its table and figures).
"""
