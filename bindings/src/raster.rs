//! `MeshScene`.

use heapgrasp_core::{MeshScene, PinholeCamera};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;

use crate::convert::{
    array_arg, check_tail, has_dtype, is_bool, named, pose_arg, short_repr, vec3_arg,
};
use crate::errors::{IntoPyResult, MeshError, UnknownMeshError};

/// Rigid triangle meshes with world poses: ground-truth silhouettes, depth and labels.
#[pyclass(name = "MeshScene", module = "heapgrasp._core")]
pub struct PyMeshScene {
    pub inner: MeshScene,
}

fn image<'py, T: numpy::Element>(
    py: Python<'py>,
    cam: &PinholeCamera,
    data: Vec<T>,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    PyArray1::from_vec(py, data).reshape([cam.height as usize, cam.width as usize])
}

/// Face indices as u32 from an int64, int32 or uint32 `(F, 3)` array.
fn faces_arg(faces: &Bound<'_, PyAny>) -> PyResult<Vec<u32>> {
    fn convert<T: Copy + std::fmt::Display>(
        data: &[T],
        to: impl Fn(T) -> Option<u32>,
    ) -> PyResult<Vec<u32>> {
        data.iter()
            .enumerate()
            .map(|(i, &x)| {
                to(x).ok_or_else(|| {
                    MeshError::new_err(format!(
                        "faces: invalid mesh: faces[{}, {}] = {x} is not a vertex index",
                        i / 3,
                        i % 3
                    ))
                })
            })
            .collect()
    }
    // The dtype picks the branch, so a wrong shape or layout is reported as such.
    if has_dtype::<i64>(faces) {
        let f = array_arg::<i64>(faces, "faces", "int64", Some(2))?;
        check_tail("faces", &f.shape, &[3], "(F, 3)")?;
        return convert(f.as_slice(), |x| u32::try_from(x).ok());
    }
    if has_dtype::<i32>(faces) {
        let f = array_arg::<i32>(faces, "faces", "int32", Some(2))?;
        check_tail("faces", &f.shape, &[3], "(F, 3)")?;
        return convert(f.as_slice(), |x| u32::try_from(x).ok());
    }
    let f = array_arg::<u32>(faces, "faces", "int64, int32 or uint32", Some(2))?;
    check_tail("faces", &f.shape, &[3], "(F, 3)")?;
    Ok(f.as_slice().to_vec())
}

/// A mesh id: an int (not a bool); anything else is an id the scene does not hold.
fn id_arg(id: &Bound<'_, PyAny>) -> PyResult<u64> {
    let unknown = || UnknownMeshError::new_err(format!("unknown mesh id {}", short_repr(id)));
    if is_bool(id) {
        return Err(unknown());
    }
    let v: i64 = id.extract().map_err(|_| unknown())?;
    u64::try_from(v).map_err(|_| UnknownMeshError::new_err(format!("unknown mesh id {v}")))
}

#[pymethods]
impl PyMeshScene {
    #[new]
    fn new() -> Self {
        Self {
            inner: MeshScene::new(),
        }
    }

    /// Adds a mesh and returns its id (>= 1).
    fn add_mesh(
        &mut self,
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        obj2world: &Bound<'_, PyAny>,
    ) -> PyResult<u64> {
        let v = array_arg::<f64>(vertices, "vertices", "float64", Some(2))?;
        check_tail("vertices", &v.shape, &[3], "(V, 3)")?;
        let faces_u32 = faces_arg(faces)?;
        let pose = pose_arg(obj2world, "obj2world")?;
        self.inner.add_mesh(v.as_slice(), &faces_u32, pose).py()
    }

    /// Moves mesh `id`.
    fn set_pose(&mut self, id: &Bound<'_, PyAny>, obj2world: &Bound<'_, PyAny>) -> PyResult<()> {
        let pose = pose_arg(obj2world, "obj2world")?;
        self.inner.set_pose(id_arg(id)?, pose).py()
    }

    /// The (4, 4) obj2world pose of mesh `id`.
    fn pose<'py>(
        &self,
        py: Python<'py>,
        id: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let m = self.inner.pose(id_arg(id)?).py()?.to_matrix();
        let flat: Vec<f64> = (0..16).map(|i| m[(i / 4, i % 4)]).collect();
        PyArray1::from_vec(py, flat).reshape([4, 4])
    }

    /// Removes mesh `id`.
    fn remove(&mut self, id: &Bound<'_, PyAny>) -> PyResult<()> {
        self.inner.remove(id_arg(id)?).py()
    }

    /// Ids of the meshes, ascending.
    fn ids(&self) -> Vec<u64> {
        self.inner.ids()
    }

    /// Whether mesh `id` is closed and consistently oriented.
    fn is_closed(&self, id: &Bound<'_, PyAny>) -> PyResult<bool> {
        self.inner.is_closed(id_arg(id)?).py()
    }

    /// Total triangle count.
    #[getter]
    fn triangle_count(&self) -> usize {
        self.inner.triangle_count()
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    /// Silhouette mask, bool (H, W).
    fn render_mask<'py>(
        &self,
        py: Python<'py>,
        #[pyo3(from_py_with = named::camera)] camera: PinholeCamera,
        cam2world: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<bool>>> {
        let pose = pose_arg(cam2world, "cam2world")?;
        let (scene, cam) = (&self.inner, camera);
        let mask = py.detach(|| scene.render_mask(&cam, &pose));
        image(py, &camera, mask.into_iter().map(|m| m != 0).collect())
    }

    /// Depth (camera z of the nearest hit, metres; 0 where nothing is hit), float32 (H, W).
    fn render_depth<'py>(
        &self,
        py: Python<'py>,
        #[pyo3(from_py_with = named::camera)] camera: PinholeCamera,
        cam2world: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let pose = pose_arg(cam2world, "cam2world")?;
        let (scene, cam) = (&self.inner, camera);
        let depth = py.detach(|| scene.render_depth(&cam, &pose));
        image(py, &camera, depth)
    }

    /// Id of the nearest mesh per pixel (0 = background), uint32 (H, W).
    fn render_labels<'py>(
        &self,
        py: Python<'py>,
        #[pyo3(from_py_with = named::camera)] camera: PinholeCamera,
        cam2world: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let pose = pose_arg(cam2world, "cam2world")?;
        let (scene, cam) = (&self.inner, camera);
        let (_, labels) = py.detach(|| scene.render_depth_labels(&cam, &pose));
        image(py, &camera, labels)
    }

    /// First hit of a world-frame ray: `(distance, id)` or None.
    fn cast_ray(
        &self,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
    ) -> PyResult<Option<(f64, u64)>> {
        let o = vec3_arg(origin, "origin")?;
        let d = vec3_arg(direction, "direction")?;
        self.inner.cast_ray(o, d).py()
    }

    fn __repr__(&self) -> String {
        format!(
            "MeshScene(meshes={}, triangles={})",
            self.inner.len(),
            self.inner.triangle_count()
        )
    }
}
