//! The kernels of Natarajan et al.'s active-vision grasp benchmark (the Python package
//! `heapgrasp.viewsphere`): the fused views' point clouds and what they show to be empty
//! (§3.2), grasp synthesis on a point cloud (§3.3) with the hand's collision check, and
//! the heuristic policies' view scores (§4.2).

pub mod clouds;
pub mod hand_points;
pub mod synthesis;
pub mod visibility;
