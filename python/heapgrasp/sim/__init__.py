"""PyBullet simulation: scenes, hand-eye camera, motion, grasping, metrics."""
