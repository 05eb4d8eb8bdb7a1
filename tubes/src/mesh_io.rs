//! Binary PLY and OBJ writers for [`TubeMesh`] (through a temporary file and a rename).
//!
//! PLY carries per-vertex `x y z nx ny nz red green blue` and triangle faces. Positions are
//! written as `float` (absolute) unless the mesh's origin is far from zero (|origin| > 1e4),
//! where `float` would round away the tube's shape: then they are `double`.

use crate::error::{write_atomic, Result, TubesError};
use crate::tube_mesh::TubeMesh;
use std::fmt::Write as _;
use std::path::Path;

/// Writes `.ply` (binary little endian) or `.obj` by the file name.
pub fn write(path: &Path, mesh: &TubeMesh) -> Result<()> {
    let name = path.to_string_lossy().to_ascii_lowercase();
    if name.ends_with(".ply") {
        write_atomic(path, ply_bytes(mesh))
    } else if name.ends_with(".obj") {
        write_atomic(path, obj_bytes(mesh).into_bytes())
    } else {
        Err(TubesError::Invalid(format!(
            "{}: mesh format unknown (use .ply or .obj)",
            path.display()
        )))
    }
}

fn wide(mesh: &TubeMesh) -> bool {
    mesh.origin.abs().max_element() > 1e4
}

/// Binary PLY bytes.
pub fn ply_bytes(mesh: &TubeMesh) -> Vec<u8> {
    let double = wide(mesh);
    let ty = if double { "double" } else { "float" };
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by umbra\nelement vertex {}\nproperty {ty} x\nproperty {ty} y\nproperty {ty} z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles()
    );
    let mut out = header.into_bytes();
    out.reserve(mesh.positions.len() * 27 + mesh.triangles() * 13);
    for i in 0..mesh.positions.len() {
        let p = mesh.positions[i].as_dvec3() + mesh.origin;
        if double {
            for v in [p.x, p.y, p.z] {
                out.extend_from_slice(&v.to_le_bytes());
            }
        } else {
            for v in [p.x, p.y, p.z] {
                out.extend_from_slice(&(v as f32).to_le_bytes());
            }
        }
        let n = mesh.normals[i];
        for v in [n.x, n.y, n.z] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&mesh.colors[i]);
    }
    for tri in mesh.indices.chunks_exact(3) {
        out.push(3);
        for &i in tri {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    out
}

/// OBJ text (vertex colours as the common `v x y z r g b` extension).
pub fn obj_bytes(mesh: &TubeMesh) -> String {
    let mut s = String::with_capacity(mesh.positions.len() * 80);
    s.push_str("# written by umbra\n");
    for (p, c) in mesh.positions.iter().zip(&mesh.colors) {
        let p = p.as_dvec3() + mesh.origin;
        let _ = writeln!(
            s,
            "v {} {} {} {:.4} {:.4} {:.4}",
            p.x,
            p.y,
            p.z,
            c[0] as f32 / 255.0,
            c[1] as f32 / 255.0,
            c[2] as f32 / 255.0
        );
    }
    for n in &mesh.normals {
        let _ = writeln!(s, "vn {} {} {}", n.x, n.y, n.z);
    }
    for t in mesh.indices.chunks_exact(3) {
        let _ = writeln!(
            s,
            "f {a}//{a} {b}//{b} {c}//{c}",
            a = t[0] + 1,
            b = t[1] + 1,
            c = t[2] + 1
        );
    }
    s
}
