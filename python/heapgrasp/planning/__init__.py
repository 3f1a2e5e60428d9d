"""Planning: grasps on the grid and views of the scene.

* grasps — :mod:`~heapgrasp.planning.volumes` (grasp volumes, eq. 15 post-processing),
  :mod:`~heapgrasp.planning.antipodal` (the analytic planner),
  :mod:`~heapgrasp.planning.grasp_network` (VGN weights), :mod:`~heapgrasp.planning.critic`
  (the learned critic);
* views — :mod:`~heapgrasp.planning.views` (eq. 12-14 scorers, fixed views),
  :mod:`~heapgrasp.planning.view_network` (eq. 13);
* :mod:`~heapgrasp.planning.selection` — next-pose selection (eq. 15-19).

What runs at grasp time only: fitting the critic, training the networks and their
evaluation are :mod:`heapgrasp.training`'s, which nothing here imports.
"""
