"""The closed loop, on any robot: configuration, the method's stages, one phase, the
clutter-removal protocol and its metrics.

* :mod:`~heapgrasp.loop.config` — :class:`RunConfig` (Table I, the run, our extensions);
* :mod:`~heapgrasp.loop.methods` — what the loop needs to know of a method (§VI-B);
* :mod:`~heapgrasp.loop.stages` — the one factory: the stages built from the config;
* :mod:`~heapgrasp.loop.phase` — one phase of a method (:class:`Pipeline`);
* :mod:`~heapgrasp.loop.extensions` — our extensions the phase calls (early stop, rim sweep);
* :mod:`~heapgrasp.loop.observe` — the observer hook;
* :mod:`~heapgrasp.loop.protocol` — §VI-C's clutter removal;
* :mod:`~heapgrasp.loop.metrics` — §VI-D metrics;
* :mod:`~heapgrasp.loop.workers` — process-pool workers' set-up.

Results (run directories, summaries, statistics) are :mod:`heapgrasp.results`.
"""
