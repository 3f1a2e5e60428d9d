"""Grasp planning on a measured grid (HEAPGrasp §IV-B): per-voxel grasp volumes (eq. 11)
from a planner, then smoothing, threshold ε and non-maximum suppression (eq. 15)."""
