//! Triangle meshes for wildlight: the [`TriMesh`] type, PLY and OBJ reading
//! and writing, and the geometric operations the other crates need (areas,
//! face normals, bounding boxes, transforms, welding of marching-cubes
//! soups, removal of small disconnected components, the support plane an
//! object stands on).
//!
//! ```no_run
//! use wildlight_mesh::TriMesh;
//! let mesh = TriMesh::read("gt/mesh_world.ply").unwrap();
//! println!("{} triangles, area {}", mesh.triangles.len(), mesh.total_area());
//! mesh.write("copy.obj").unwrap();
//! ```

mod components;
mod error;
pub mod obj;
pub mod ply;
mod support;
mod trimesh;
mod weld;

pub use error::MeshError;
pub use support::{ObjectOnly, SupportPlane, SupportSearch, fit_plane};
pub use trimesh::{Aabb, TriMesh};
