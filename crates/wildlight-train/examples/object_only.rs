//! Cuts a mesh exported from a maskless run down to the object: the
//! triangles outside the capture's unit sphere, the support plane (a
//! table) and what lies below it, then every piece but the largest
//! (`TriMesh::object_only`), for `wildlight eval mesh` to measure the
//! object alone.
//!
//! ```text
//! cargo run --release -p wildlight-train --example object_only -- MESH_IN CAPTURE MESH_OUT
//! ```

use anyhow::Context;
use wildlight_mesh::{SupportSearch, TriMesh};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [input, capture, output] = args.as_slice() else {
        anyhow::bail!("usage: object_only MESH_IN CAPTURE MESH_OUT");
    };
    let mesh = TriMesh::read(input).with_context(|| format!("cannot read {input}"))?;
    let cameras = wildlight_data::Dataset::load_cameras(std::path::Path::new(capture))?;
    let camera = cameras.first().context("the capture has no camera")?;
    let centre = camera.to_world(glam::DVec3::ZERO).as_vec3();
    let radius = camera.world_scale() as f32;
    let cut = mesh.object_only(&SupportSearch::new(centre, radius));
    println!(
        "plane {:?}; support area {:.4}, outside area {:.4}, fragment area {:.4}; {} of {} triangles kept",
        cut.plane,
        cut.support_area,
        cut.outside_area,
        cut.fragment_area,
        cut.mesh.triangles.len(),
        mesh.triangles.len()
    );
    cut.mesh.write(output)?;
    Ok(())
}
