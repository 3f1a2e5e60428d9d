"""The closed loop, on any robot: configuration, one phase, the clutter-removal protocol,
metrics and statistics.

* :mod:`~heapgrasp.loop.config` — :class:`RunConfig` (Table I, the run, our extensions);
* :mod:`~heapgrasp.loop.phase` — one phase of a method (:class:`Pipeline`);
* :mod:`~heapgrasp.loop.policies` — the extensions the phase calls (early stop, rim sweep);
* :mod:`~heapgrasp.loop.protocol` — §VI-C's clutter removal;
* :mod:`~heapgrasp.loop.metrics`, :mod:`~heapgrasp.loop.stats` — §VI-D metrics, intervals.
"""
