"""The active-vision grasp benchmark of seed ``001_95c7dd5c6a7c3646.txt``: a depth camera
on a viewsphere moves 20° at a time until the views it fused yield a grasp.

The system is one package over the shared layers (geometry, perception, planning, the
simulator's objects and optics, the Rust core's cloud, visibility and synthesis
kernels). Its modules, each importing only those listed after it (checked by
import-linter in ``scripts/check``):

* :mod:`~heapgrasp.viewsphere.bench` -- ``heapgrasp viewsphere bench``: objects × poses
  on a process pool or Ray, resumable records;
* :mod:`~heapgrasp.viewsphere.training` -- PCA + LR/LDA and the DQN fitted and exported
  to ONNX (scikit-learn, PyTorch: only training imports it);
* :mod:`~heapgrasp.viewsphere.data` -- the supervised policies' paths dataset;
  :mod:`~heapgrasp.viewsphere.report` -- summaries, Fig. 10/11, Table 1;
  :mod:`~heapgrasp.viewsphere.episode` -- one object pose, every policy's episode;
* :mod:`~heapgrasp.viewsphere.execute` -- a found grasp executed by the free-flying hand
  (PyBullet); :mod:`~heapgrasp.viewsphere.world` -- the object on its table, rendered
  from the sphere;
* :mod:`~heapgrasp.viewsphere.objects` -- the YCB stand-ins, the training shapes, your
  meshes at rest; :mod:`~heapgrasp.viewsphere.protocol` -- the yaws, the resting poses;
* :mod:`~heapgrasp.viewsphere.learned` (§4.3), :mod:`~heapgrasp.viewsphere.heapgrasp_views`
  (HEAPGrasp's eq. 14 as a policy), :mod:`~heapgrasp.viewsphere.grasps` (fused clouds,
  the unexplored region, grasp synthesis: §3.2–3.3);
* :mod:`~heapgrasp.viewsphere.heuristics` -- Algorithms 1 and 2, information gain (§4.2);
* :mod:`~heapgrasp.viewsphere.policies` -- the policy protocols, random, brick, BFS;
* :mod:`~heapgrasp.viewsphere.sphere` -- the discrete viewsphere (§3.1).

Only ``world``, ``execute`` and what runs them reach PyBullet.
"""
