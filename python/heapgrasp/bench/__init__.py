"""Benchmarks behind ``heapgrasp bench``.

Each benchmark is a module with the function that runs it from the parsed options (its
command line is built in :mod:`heapgrasp.cli.bench`):

* :mod:`heapgrasp.bench.carve` -- ``heapgrasp bench carve``: Shape-from-Silhouette
  carving, the Rust kernel against NumPy, numba and Open3D;
* :mod:`heapgrasp.bench.world` -- ``heapgrasp bench world``: ground-truth masks vs
  PyBullet rendering, seconds per simulated grasp phase;
* :mod:`heapgrasp.bench.sim` -- ``heapgrasp bench sim``: the closed loop of HEAPGrasp and
  its baselines on seed 000's protocol (Tables II/III, Fig. 4/5);
* :mod:`heapgrasp.bench.grasp` -- ``heapgrasp bench grasp``: the analytic antipodal grasp
  planner on circle / dense Shape-from-Silhouette grids, one executed grasp per scene;
* :mod:`heapgrasp.bench.topk` -- ``heapgrasp bench topk``: each grasp planner's best
  few grasps on the grids the closed loop meets, labelled on the true meshes;
* :mod:`heapgrasp.bench.compare` -- ``heapgrasp bench compare``: two finished runs on
  the same scenes, success rates with intervals and their paired difference;
* :mod:`heapgrasp.bench.seg` -- ``heapgrasp bench seg``: the segmentation network's CPU
  time per frame, per encoder;
* :mod:`heapgrasp.bench.paper_tables` -- ``heapgrasp bench noise`` and ``heapgrasp bench
  clutter``: HEAPGrasp's Tables V (mask noise) and IV (clutter) in simulation.

Scenes shared by the benchmarks live in :mod:`heapgrasp.bench.scenes`, a benchmark
folder's ``summary.md`` page in :mod:`heapgrasp.results.pages`. The viewsphere benchmark
(``heapgrasp viewsphere bench``) lives with the rest of its system in
:mod:`heapgrasp.viewsphere`.
"""
