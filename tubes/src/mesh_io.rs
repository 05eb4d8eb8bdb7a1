//! Binary PLY and OBJ writers for [`TubeMesh`] (through a temporary file and a rename).
//!
//! PLY carries per-vertex `x y z nx ny nz red green blue` and triangle faces. Positions are
//! written as `float` (absolute) unless the mesh's origin is far from zero (|origin| > 1e4),
//! where `float` would round away the tube's shape: then they are `double`.

use crate::error::{Result, TubesError};
use crate::tube_mesh::TubeMesh;
use std::path::Path;

/// Writes `.ply` (binary little endian) or `.obj` by the file name, streamed through a
/// temporary file (the file's bytes are never held whole: a mesh of 10^8 triangles would
/// need another 1.3 GB).
pub fn write(path: &Path, mesh: &TubeMesh) -> Result<()> {
    let name = path.to_string_lossy().to_ascii_lowercase();
    if name.ends_with(".ply") {
        volume::write_atomic_with(path, |w| write_ply(w, mesh)).map_err(TubesError::from)
    } else if name.ends_with(".obj") {
        volume::write_atomic_with(path, |w| write_obj(w, mesh)).map_err(TubesError::from)
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
    let mut out = Vec::with_capacity(mesh.positions.len() * 27 + mesh.triangles() * 13 + 400);
    write_ply(&mut out, mesh).expect("writing to memory");
    out
}

/// The binary PLY header of a mesh of `vertices` vertices and `triangles` triangles, positions
/// in `double` when `double`.
fn ply_header(vertices: usize, triangles: usize, double: bool) -> String {
    let ty = if double { "double" } else { "float" };
    format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by umbra\nelement vertex {vertices}\nproperty {ty} x\nproperty {ty} y\nproperty {ty} z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face {triangles}\nproperty list uchar int vertex_indices\nend_header\n"
    )
}

/// Bytes of a PLY vertex record (positions in `double` or `float`, three float normals, three
/// colour bytes) and of a triangle record (a count byte and three `int`s).
fn record_bytes(double: bool) -> (u64, u64) {
    (if double { 24 } else { 12 } + 12 + 3, 13)
}

/// Vertex records of `positions` (relative to `origin`), `normals`, `colors` to `w`, in pieces
/// of about 1 MiB through `out`.
fn write_vertices(
    w: &mut dyn std::io::Write,
    out: &mut Vec<u8>,
    origin: glam::DVec3,
    double: bool,
    (positions, normals, colors): (&[glam::Vec3], &[glam::Vec3], &[[u8; 3]]),
) -> std::io::Result<()> {
    out.clear();
    for i in 0..positions.len() {
        let p = positions[i].as_dvec3() + origin;
        if double {
            for v in [p.x, p.y, p.z] {
                out.extend_from_slice(&v.to_le_bytes());
            }
        } else {
            for v in [p.x, p.y, p.z] {
                out.extend_from_slice(&(v as f32).to_le_bytes());
            }
        }
        let n = normals[i];
        for v in [n.x, n.y, n.z] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&colors[i]);
        if out.len() >= 1 << 20 {
            w.write_all(out)?;
            out.clear();
        }
    }
    w.write_all(out)
}

/// Triangle records of `indices` to `w`, in pieces of about 1 MiB through `out`.
fn write_faces(
    w: &mut dyn std::io::Write,
    out: &mut Vec<u8>,
    indices: &[u32],
) -> std::io::Result<()> {
    out.clear();
    for tri in indices.chunks_exact(3) {
        out.push(3);
        for &i in tri {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
        if out.len() >= 1 << 20 {
            w.write_all(out)?;
            out.clear();
        }
    }
    w.write_all(out)
}

/// Binary PLY to `w`, in pieces of about 1 MiB.
pub fn write_ply(w: &mut dyn std::io::Write, mesh: &TubeMesh) -> std::io::Result<()> {
    if mesh.positions.len() > i32::MAX as usize {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "{} vertices; PLY's indices are signed 32-bit integers (at most {})",
                mesh.positions.len(),
                i32::MAX
            ),
        ));
    }
    let double = wide(mesh);
    w.write_all(ply_header(mesh.positions.len(), mesh.triangles(), double).as_bytes())?;
    let mut out: Vec<u8> = Vec::with_capacity(1 << 20);
    let v = (&mesh.positions[..], &mesh.normals[..], &mesh.colors[..]);
    write_vertices(w, &mut out, mesh.origin, double, v)?;
    write_faces(w, &mut out, &mesh.indices)
}

/// A binary PLY written part by part as [`crate::tube_mesh::build_streamed`] meshes it: the
/// header once the mesh's size is known, then each part's vertex and triangle records at
/// their places in the file (the records have fixed sizes, so a part's offsets follow from
/// its first vertex and index), through a temporary file renamed by [`PlyStream::finish`]
/// (removed when the stream is dropped unfinished). The same bytes as [`write_ply`] of the
/// whole mesh.
pub struct PlyStream {
    path: std::path::PathBuf,
    tmp: std::path::PathBuf,
    file: std::fs::File,
    origin: glam::DVec3,
    double: bool,
    header: u64,
    vertices: u64,
    out: Vec<u8>,
    finished: bool,
    /// Seconds spent writing so far (the mesher's time is the rest).
    pub seconds: f64,
}

impl PlyStream {
    /// Creates the temporary file beside `path`.
    pub fn create(path: &Path) -> Result<PlyStream> {
        let t = std::time::Instant::now();
        volume::check_not_read(&[Some(path)]).map_err(volume::VolumeError::Invalid)?;
        let tmp = volume::temp_path(path)?;
        volume::writing(&tmp, true);
        let file = std::fs::File::create(&tmp).map_err(|e| {
            volume::writing(&tmp, false);
            TubesError::io(path, e)
        })?;
        let seconds = t.elapsed().as_secs_f64();
        Ok(PlyStream {
            path: path.to_path_buf(),
            tmp,
            file,
            origin: glam::DVec3::ZERO,
            double: false,
            header: 0,
            vertices: 0,
            out: Vec::with_capacity(1 << 20),
            finished: false,
            seconds,
        })
    }

    /// Writes `bytes` (through `write`) at `offset` of the temporary file.
    fn write_at(
        &mut self,
        offset: u64,
        write: impl FnOnce(&mut dyn std::io::Write, &mut Vec<u8>) -> std::io::Result<()>,
    ) -> Result<()> {
        use std::io::Seek;
        let t = std::time::Instant::now();
        let res = (|| {
            self.file.seek(std::io::SeekFrom::Start(offset))?;
            write(&mut self.file, &mut self.out)
        })();
        self.seconds += t.elapsed().as_secs_f64();
        res.map_err(|e| TubesError::io(&self.path, e))
    }

    /// Flushes the file to disk and renames it to its path; the seconds spent on the file in
    /// all (creating it, sizing it, the writes, the flush and the rename).
    pub fn finish(mut self) -> Result<f64> {
        let t = std::time::Instant::now();
        let res = self
            .file
            .sync_all()
            .and_then(|_| std::fs::rename(&self.tmp, &self.path));
        self.seconds += t.elapsed().as_secs_f64();
        res.map_err(|e| TubesError::io(&self.path, e))?;
        self.finished = true;
        Ok(self.seconds)
    }
}

impl Drop for PlyStream {
    fn drop(&mut self) {
        if !self.finished {
            let _ = std::fs::remove_file(&self.tmp);
        }
        volume::writing(&self.tmp, false);
    }
}

impl crate::tube_mesh::MeshSink for PlyStream {
    fn begin(
        &mut self,
        origin: glam::DVec3,
        vertices: usize,
        indices: usize,
        _stats: &crate::tube_mesh::TubeStats,
    ) -> Result<()> {
        if vertices > i32::MAX as usize {
            return Err(TubesError::Invalid(format!(
                "{}: {vertices} vertices; PLY's indices are signed 32-bit integers (at most \
                 {}): mesh fewer streamlines",
                self.path.display(),
                i32::MAX
            )));
        }
        self.origin = origin;
        self.double = origin.abs().max_element() > 1e4;
        self.vertices = vertices as u64;
        let header = ply_header(vertices, indices / 3, self.double);
        self.header = header.len() as u64;
        let (vb, fb) = record_bytes(self.double);
        let total = self.header + vertices as u64 * vb + (indices / 3) as u64 * fb;
        self.write_at(0, |w, _| w.write_all(header.as_bytes()))?;
        // The file at its final size at once: the parts fill it in (file I/O, timed as the
        // writes are).
        let t = std::time::Instant::now();
        let res = self.file.set_len(total);
        self.seconds += t.elapsed().as_secs_f64();
        res.map_err(|e| TubesError::io(&self.path, e))
    }

    fn part(&mut self, p: &crate::tube_mesh::MeshPart<'_>) -> Result<()> {
        let (vb, fb) = record_bytes(self.double);
        let (origin, double) = (self.origin, self.double);
        self.write_at(self.header + p.first_vertex as u64 * vb, |w, out| {
            write_vertices(w, out, origin, double, (p.positions, p.normals, p.colors))
        })?;
        let faces = self.header + self.vertices * vb + (p.first_index / 3) as u64 * fb;
        self.write_at(faces, |w, out| write_faces(w, out, p.indices))
    }
}

/// OBJ text (vertex colours as the common `v x y z r g b` extension).
pub fn obj_bytes(mesh: &TubeMesh) -> String {
    let mut out = Vec::with_capacity(mesh.positions.len() * 80);
    write_obj(&mut out, mesh).expect("writing to memory");
    String::from_utf8(out).expect("OBJ text is ASCII")
}

/// OBJ text to `w`.
pub fn write_obj(w: &mut dyn std::io::Write, mesh: &TubeMesh) -> std::io::Result<()> {
    writeln!(w, "# written by umbra")?;
    for (p, c) in mesh.positions.iter().zip(&mesh.colors) {
        let p = p.as_dvec3() + mesh.origin;
        writeln!(
            w,
            "v {} {} {} {:.4} {:.4} {:.4}",
            p.x,
            p.y,
            p.z,
            c[0] as f32 / 255.0,
            c[1] as f32 / 255.0,
            c[2] as f32 / 255.0
        )?;
    }
    for n in &mesh.normals {
        writeln!(w, "vn {} {} {}", n.x, n.y, n.z)?;
    }
    for t in mesh.indices.chunks_exact(3) {
        writeln!(
            w,
            "f {a}//{a} {b}//{b} {c}//{c}",
            a = t[0] + 1,
            b = t[1] + 1,
            c = t[2] + 1
        )?;
    }
    Ok(())
}

/// Reads a triangle mesh: `.ply` (ASCII, binary little or big endian; vertex `x y z`, optional
/// `nx ny nz` and `red green blue` as uchar or float; faces as a list, polygons fanned into
/// triangles) or `.obj` (`v` with optional colour, `vn`, `f` with `v`, `v/t`, `v//n`, `v/t/n`
/// and negative indices; polygons fanned). Without normals (or with OBJ normals not per
/// position) vertex normals are the area-weighted face normals; without colours vertices are
/// light grey. Positions are stored relative to their mean as origin. Errors name the file
/// and the element, line or field.
pub fn read(path: &Path) -> Result<TubeMesh> {
    let bytes = volume::read_regular(path, None).map_err(|e| TubesError::io(path, e))?;
    let name = path.to_string_lossy().to_ascii_lowercase();
    let (pos, mut normals, colors, indices) = if name.ends_with(".ply") {
        read_ply(path, &bytes)?
    } else if name.ends_with(".obj") {
        read_obj(path, &bytes)?
    } else {
        return Err(TubesError::Invalid(format!(
            "{}: mesh format unknown (use .ply or .obj)",
            path.display()
        )));
    };
    if let Some(&bad) = indices.iter().find(|&&i| i as usize >= pos.len()) {
        return Err(TubesError::format(
            path,
            "faces",
            format!("vertex index {bad} with {} vertices", pos.len()),
        ));
    }
    // Finite and within the coordinates a volume may have (beyond them positions relative
    // to the mean leave f32's useful range; 1e100 became infinite).
    let far = volume::MAX_COORDINATE;
    if let Some(i) = pos
        .iter()
        .position(|p| !(p.is_finite() && p.abs().max_element() <= far))
    {
        return Err(TubesError::format(
            path,
            "vertices",
            format!(
                "vertex {i} at {:?} is not within {far:e} of the origin",
                pos[i]
            ),
        ));
    }
    // Normals the file gives that are not finite are recomputed.
    if normals.len() != pos.len() || normals.iter().any(|n| !n.is_finite()) {
        normals = vertex_normals(&pos, &indices);
    }
    let n = pos.len().max(1) as f64;
    let origin = pos.iter().fold(glam::DVec3::ZERO, |a, p| a + *p) / n;
    Ok(TubeMesh {
        origin,
        positions: pos.iter().map(|p| (*p - origin).as_vec3()).collect(),
        normals,
        colors: if colors.len() == pos.len() {
            colors
        } else {
            vec![[200, 200, 200]; pos.len()]
        },
        indices,
        radius: 0.0,
        opacity: None,
    })
}

type MeshParts = (Vec<glam::DVec3>, Vec<glam::Vec3>, Vec<[u8; 3]>, Vec<u32>);

fn vertex_normals(pos: &[glam::DVec3], idx: &[u32]) -> Vec<glam::Vec3> {
    let mut n = vec![glam::DVec3::ZERO; pos.len()];
    for t in idx.chunks_exact(3) {
        let (a, b, c) = (pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize]);
        let f = (b - a).cross(c - a);
        for &i in t {
            n[i as usize] += f;
        }
    }
    n.iter().map(|v| v.normalize_or_zero().as_vec3()).collect()
}

fn fan(poly: &[u32], out: &mut Vec<u32>) {
    for i in 1..poly.len().saturating_sub(1) {
        out.extend([poly[0], poly[i], poly[i + 1]]);
    }
}

fn read_obj(path: &Path, bytes: &[u8]) -> Result<MeshParts> {
    let text =
        std::str::from_utf8(bytes).map_err(|_| TubesError::format(path, "text", "not UTF-8"))?;
    let (mut pos, mut cols, mut vn) = (vec![], vec![], vec![]);
    let mut normal_of: Vec<Option<u32>> = vec![];
    let mut idx = vec![];
    for (ln, line) in text.lines().enumerate() {
        let bad =
            |what: &str| TubesError::format(path, format!("line {}", ln + 1), what.to_string());
        let mut it = line.split_whitespace();
        let nums = |it: std::str::SplitWhitespace| -> std::result::Result<Vec<f64>, TubesError> {
            it.map(|s| {
                s.parse::<f64>()
                    .map_err(|_| bad(&format!("'{s}' is not a number")))
            })
            .collect()
        };
        match it.next() {
            Some("v") => {
                let v = nums(it)?;
                if v.len() < 3 {
                    return Err(bad("a vertex needs x y z"));
                }
                pos.push(glam::DVec3::new(v[0], v[1], v[2]));
                if v.len() >= 6 {
                    cols.push([0, 1, 2].map(|k| (v[3 + k].clamp(0.0, 1.0) * 255.0).round() as u8));
                }
            }
            Some("vn") => {
                let v = nums(it)?;
                if v.len() < 3 {
                    return Err(bad("a normal needs x y z"));
                }
                vn.push(
                    glam::DVec3::new(v[0], v[1], v[2])
                        .normalize_or_zero()
                        .as_vec3(),
                );
            }
            Some("f") => {
                let mut poly = vec![];
                for tok in it {
                    let mut parts = tok.split('/');
                    let resolve =
                        |s: Option<&str>,
                         n: usize|
                         -> std::result::Result<Option<u32>, TubesError> {
                            match s.filter(|s| !s.is_empty()) {
                                None => Ok(None),
                                Some(s) => {
                                    let i: i64 = s.parse().map_err(|_| {
                                        bad(&format!("'{tok}' is not a face index"))
                                    })?;
                                    let j = if i < 0 { n as i64 + i } else { i - 1 };
                                    if j < 0 || j >= n as i64 {
                                        return Err(bad(&format!("index {i} with {n} defined")));
                                    }
                                    Ok(Some(j as u32))
                                }
                            }
                        };
                    let v = resolve(parts.next(), pos.len())?
                        .ok_or_else(|| bad(&format!("'{tok}' has no vertex index")))?;
                    let _ = parts.next();
                    let n = resolve(parts.next(), vn.len())?;
                    if normal_of.len() < pos.len() {
                        normal_of.resize(pos.len(), None);
                    }
                    if n.is_some() {
                        normal_of[v as usize] = n;
                    }
                    poly.push(v);
                }
                if poly.len() < 3 {
                    return Err(bad("a face needs three vertices"));
                }
                fan(&poly, &mut idx);
            }
            _ => {}
        }
    }
    normal_of.resize(pos.len(), None);
    let normals = if !vn.is_empty() && normal_of.iter().all(|n| n.is_some()) {
        normal_of.iter().map(|n| vn[n.unwrap() as usize]).collect()
    } else {
        vec![]
    };
    Ok((pos, normals, cols, idx))
}

/// A PLY scalar type: size in bytes and how to read one.
#[derive(Clone, Copy, Debug)]
enum PlyType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl PlyType {
    fn parse(s: &str) -> Option<PlyType> {
        Some(match s {
            "char" | "int8" => PlyType::I8,
            "uchar" | "uint8" => PlyType::U8,
            "short" | "int16" => PlyType::I16,
            "ushort" | "uint16" => PlyType::U16,
            "int" | "int32" => PlyType::I32,
            "uint" | "uint32" => PlyType::U32,
            "float" | "float32" => PlyType::F32,
            "double" | "float64" => PlyType::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            PlyType::I8 | PlyType::U8 => 1,
            PlyType::I16 | PlyType::U16 => 2,
            PlyType::I32 | PlyType::U32 | PlyType::F32 => 4,
            PlyType::F64 => 8,
        }
    }
    fn read(self, b: &[u8], big: bool) -> f64 {
        macro_rules! rd {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().unwrap();
                (if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f64
            }};
        }
        match self {
            PlyType::I8 => b[0] as i8 as f64,
            PlyType::U8 => b[0] as f64,
            PlyType::I16 => rd!(i16, 2),
            PlyType::U16 => rd!(u16, 2),
            PlyType::I32 => rd!(i32, 4),
            PlyType::U32 => rd!(u32, 4),
            PlyType::F32 => rd!(f32, 4),
            PlyType::F64 => rd!(f64, 8),
        }
    }
}

enum PlyProp {
    Scalar(String, PlyType),
    List(String, PlyType, PlyType),
}

struct PlyElement {
    name: String,
    count: usize,
    props: Vec<PlyProp>,
}

fn read_ply(path: &Path, bytes: &[u8]) -> Result<MeshParts> {
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n" || w.starts_with(b"end_header\r"))
        .ok_or_else(|| TubesError::format(path, "header", "no end_header"))?;
    let header = std::str::from_utf8(&bytes[..end])
        .map_err(|_| TubesError::format(path, "header", "not text"))?;
    let mut body = &bytes[end..];
    let nl = body.iter().position(|&b| b == b'\n').unwrap_or(body.len());
    body = &body[(nl + 1).min(body.len())..];
    let mut lines = header.lines();
    if lines.next().map(str::trim) != Some("ply") {
        return Err(TubesError::format(path, "magic", "not a PLY file"));
    }
    let mut format = "";
    let mut elements: Vec<PlyElement> = vec![];
    for line in lines {
        let t: Vec<&str> = line.split_whitespace().collect();
        let bad =
            |p: &str| TubesError::format(path, format!("header line '{line}'"), p.to_string());
        match t.first().copied() {
            Some("format") => format = t.get(1).copied().unwrap_or(""),
            Some("element") => {
                let count = t
                    .get(2)
                    .and_then(|c| c.parse::<usize>().ok())
                    .ok_or_else(|| bad("element count"))?;
                if count > bytes.len() {
                    return Err(bad("more elements than the file has bytes"));
                }
                elements.push(PlyElement {
                    name: t.get(1).unwrap_or(&"").to_string(),
                    count,
                    props: vec![],
                });
            }
            Some("property") => {
                let e = elements
                    .last_mut()
                    .ok_or_else(|| bad("property before element"))?;
                if t.get(1) == Some(&"list") {
                    let (c, i) = (
                        t.get(2).and_then(|s| PlyType::parse(s)),
                        t.get(3).and_then(|s| PlyType::parse(s)),
                    );
                    match (c, i, t.get(4)) {
                        (Some(c), Some(i), Some(n)) => {
                            e.props.push(PlyProp::List(n.to_string(), c, i))
                        }
                        _ => return Err(bad("unknown list type")),
                    }
                } else {
                    match (t.get(1).and_then(|s| PlyType::parse(s)), t.get(2)) {
                        (Some(ty), Some(n)) => e.props.push(PlyProp::Scalar(n.to_string(), ty)),
                        _ => return Err(bad("unknown property type")),
                    }
                }
            }
            _ => {}
        }
    }
    let big = match format {
        "ascii" => None,
        "binary_little_endian" => Some(false),
        "binary_big_endian" => Some(true),
        f => {
            return Err(TubesError::format(
                path,
                "format",
                format!("'{f}' is not a PLY format"),
            ))
        }
    };
    let text: Vec<&str> = match big {
        None => std::str::from_utf8(body)
            .map_err(|_| TubesError::format(path, "body", "not text"))?
            .split_whitespace()
            .collect(),
        Some(_) => vec![],
    };
    let (mut ti, mut bi) = (0usize, 0usize);
    let short = |what: &str| TubesError::format(path, what.to_string(), "the file ends early");
    let mut next = |ty: PlyType, what: &str| -> Result<f64> {
        match big {
            None => {
                let s = text.get(ti).ok_or_else(|| short(what))?;
                ti += 1;
                s.parse::<f64>().map_err(|_| {
                    TubesError::format(path, what.to_string(), format!("'{s}' is not a number"))
                })
            }
            Some(be) => {
                let n = ty.size();
                let b = body.get(bi..bi + n).ok_or_else(|| short(what))?;
                bi += n;
                Ok(ty.read(b, be))
            }
        }
    };
    let (mut pos, mut normals, mut cols, mut idx) = (vec![], vec![], vec![], vec![]);
    for e in &elements {
        for _ in 0..e.count {
            let mut v = [f64::NAN; 9];
            let mut float_colour = false;
            for p in &e.props {
                match p {
                    PlyProp::Scalar(n, ty) => {
                        let x = next(*ty, &format!("element {} property {n}", e.name))?;
                        let k = ["x", "y", "z", "nx", "ny", "nz", "red", "green", "blue"]
                            .iter()
                            .position(|k| k == n);
                        if let Some(k) = k {
                            v[k] = x;
                            if k >= 6 && matches!(ty, PlyType::F32 | PlyType::F64) {
                                float_colour = true;
                            }
                        }
                    }
                    PlyProp::List(n, ct, it) => {
                        let what = format!("element {} list {n}", e.name);
                        let c = next(*ct, &what)?;
                        if !(0.0..=1e6).contains(&c) {
                            return Err(TubesError::format(path, what, format!("list length {c}")));
                        }
                        let mut poly = Vec::with_capacity(c as usize);
                        for _ in 0..c as usize {
                            let i = next(*it, &what)?;
                            if !(i >= 0.0 && i < u32::MAX as f64) {
                                return Err(TubesError::format(path, what, format!("index {i}")));
                            }
                            poly.push(i as u32);
                        }
                        if e.name == "face" && (n == "vertex_indices" || n == "vertex_index") {
                            fan(&poly, &mut idx);
                        }
                    }
                }
            }
            if e.name == "vertex" {
                if v[..3].iter().any(|x| x.is_nan()) {
                    return Err(TubesError::format(
                        path,
                        "element vertex",
                        "needs x, y and z",
                    ));
                }
                pos.push(glam::DVec3::new(v[0], v[1], v[2]));
                if !v[3..6].iter().any(|x| x.is_nan()) {
                    normals.push(
                        glam::DVec3::new(v[3], v[4], v[5])
                            .normalize_or_zero()
                            .as_vec3(),
                    );
                }
                if !v[6..9].iter().any(|x| x.is_nan()) {
                    let s = if float_colour { 255.0 } else { 1.0 };
                    cols.push([6, 7, 8].map(|k| (v[k] * s).round().clamp(0.0, 255.0) as u8));
                }
            }
        }
    }
    Ok((pos, normals, cols, idx))
}

#[cfg(test)]
mod read_tests {
    use super::*;

    fn sample() -> TubeMesh {
        TubeMesh {
            origin: glam::DVec3::new(10.0, 20.0, 30.0),
            positions: vec![
                glam::Vec3::new(0.0, 0.0, 0.0),
                glam::Vec3::new(1.0, 0.0, 0.0),
                glam::Vec3::new(0.0, 1.0, 0.0),
                glam::Vec3::new(1.0, 1.0, 0.5),
            ],
            normals: vec![glam::Vec3::Z; 4],
            colors: vec![[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30]],
            indices: vec![0, 1, 2, 1, 3, 2],
            opacity: None,
            radius: 0.0,
        }
    }

    fn same(a: &TubeMesh, b: &TubeMesh) {
        assert_eq!(a.indices, b.indices);
        for i in 0..a.positions.len() {
            let (p, q) = (
                a.positions[i].as_dvec3() + a.origin,
                b.positions[i].as_dvec3() + b.origin,
            );
            assert!((p - q).length() < 1e-4, "{p} {q}");
            assert!((a.normals[i] - b.normals[i]).length() < 1e-4);
        }
    }

    #[test]
    fn ply_and_obj_round_trip_through_our_writers() {
        let dir = tempfile::tempdir().unwrap();
        let m = sample();
        for ext in ["ply", "obj"] {
            let p = dir.path().join(format!("m.{ext}"));
            write(&p, &m).unwrap();
            let r = read(&p).unwrap();
            same(&m, &r);
            assert_eq!(r.colors[0], [255, 0, 0]);
            assert_eq!(r.colors[3], [10, 20, 30]);
        }
    }

    #[test]
    fn ascii_ply_quads_and_obj_polygons_are_fanned_and_normals_computed() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("q.ply");
        std::fs::write(
            &p,
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",
        )
        .unwrap();
        let m = read(&p).unwrap();
        assert_eq!(m.indices, vec![0, 1, 2, 0, 2, 3]);
        assert!(m
            .normals
            .iter()
            .all(|n| (*n - glam::Vec3::Z).length() < 1e-6));
        let o = dir.path().join("q.obj");
        std::fs::write(
            &o,
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1 2/2 3/3 -1/4\n",
        )
        .unwrap();
        assert_eq!(read(&o).unwrap().indices, vec![0, 1, 2, 0, 2, 3]);
    }

    #[test]
    fn malformed_meshes_are_named_errors() {
        let dir = tempfile::tempdir().unwrap();
        let cases: [(&str, &str, &str); 5] = [
            ("a.obj", "v 0 0 0\nv 1 0 0\nf 1 2 9\n", "line 3"),
            ("b.obj", "v 0 0 x\n", "'x'"),
            ("c.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n", "ends early"),
            ("d.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 99999999999\nproperty float x\nend_header\n", "more elements"),
            ("e.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", "vertex index 7"),
        ];
        for (name, text, needle) in cases {
            let p = dir.path().join(name);
            std::fs::write(&p, text).unwrap();
            let e = read(&p).unwrap_err().to_string();
            assert!(e.contains(name) && e.contains(needle), "{name}: {e}");
        }
    }
}

#[cfg(test)]
mod stream_tests {
    use super::*;
    use crate::tube_mesh::{
        build_owned, build_streamed_by, MeshPart, MeshSink, TubeOptions, TubeStats,
    };

    /// 300 streamlines of 40 points in bundles, far from the origin on one side so that the
    /// PLY of the second test carries `double` positions.
    fn lines(shift: f32) -> crate::Streamlines {
        let b = crate::synthetic::Bundles {
            count: 300,
            points: 40,
            ..Default::default()
        };
        let mut s = crate::Streamlines::new();
        let mut line = vec![];
        for i in 0..b.count {
            b.line(i, &mut line);
            let moved: Vec<glam::Vec3> =
                line.iter().map(|p| *p + glam::Vec3::splat(shift)).collect();
            s.push(&moved);
        }
        s
    }

    /// Collects the parts into one mesh, checking that they arrive in order.
    #[derive(Default)]
    struct Gather {
        mesh: TubeMesh,
        size: (usize, usize),
        parts: usize,
        buffers: Option<[usize; 2]>,
    }

    impl MeshSink for Gather {
        fn begin(&mut self, origin: glam::DVec3, v: usize, i: usize, _: &TubeStats) -> Result<()> {
            self.mesh.origin = origin;
            self.size = (v, i);
            Ok(())
        }
        fn part(&mut self, p: &MeshPart<'_>) -> Result<()> {
            // Every part in the same buffers: allocated once, at the largest part's size.
            let at = [p.positions.as_ptr() as usize, p.indices.as_ptr() as usize];
            assert_eq!(*self.buffers.get_or_insert(at), at, "part {}", self.parts);
            assert_eq!(p.first_vertex, self.mesh.positions.len());
            assert_eq!(p.first_index, self.mesh.indices.len());
            self.mesh.positions.extend_from_slice(p.positions);
            self.mesh.normals.extend_from_slice(p.normals);
            self.mesh.colors.extend_from_slice(p.colors);
            self.mesh.indices.extend_from_slice(p.indices);
            self.parts += 1;
            Ok(())
        }
    }

    /// Meshed part by part (parts of at most 2,000 vertices: dozens of them), the mesh is the
    /// whole build's, vertex for vertex and index for index, with the same statistics.
    #[test]
    fn a_mesh_streamed_in_parts_is_the_whole_mesh() {
        let o = TubeOptions::defaults(0.3, 8, 0.05);
        let (whole, st) = build_owned(lines(0.0), &o);
        let mut g = Gather::default();
        let (st2, vertices) = build_streamed_by(lines(0.0), &o, &mut g, |_| 2000).unwrap();
        assert!(g.parts > 20, "{} parts", g.parts);
        assert_eq!(g.size, (whole.positions.len(), whole.indices.len()));
        assert_eq!(vertices, whole.positions.len());
        assert_eq!(g.mesh.origin, whole.origin);
        assert!(g.mesh.positions == whole.positions && g.mesh.normals == whole.normals);
        assert!(g.mesh.colors == whole.colors && g.mesh.indices == whole.indices);
        assert_eq!(st.triangles, st2.triangles);
        assert_eq!(st.min_section_ratio, st2.min_section_ratio);
        assert_eq!(st.max_deviation, st2.max_deviation);
    }

    /// The PLY written part by part at the records' places is `write_ply`'s file of the whole
    /// mesh, byte for byte (float positions, and double ones far from the origin); an
    /// unfinished stream leaves no file and no temporary.
    #[test]
    fn a_ply_streamed_in_parts_is_the_whole_meshs_file() {
        let dir = tempfile::tempdir().unwrap();
        let o = TubeOptions::defaults(0.3, 8, 0.05);
        for shift in [0.0f32, 5e4] {
            let (whole, _) = build_owned(lines(shift), &o);
            assert_eq!(wide(&whole), shift > 0.0);
            let path = dir.path().join("t.ply");
            let mut ply = PlyStream::create(&path).unwrap();
            build_streamed_by(lines(shift), &o, &mut ply, |_| 2000).unwrap();
            ply.finish().unwrap();
            assert!(
                std::fs::read(&path).unwrap() == ply_bytes(&whole),
                "shift {shift}"
            );
        }
        let path = dir.path().join("u.ply");
        let mut ply = PlyStream::create(&path).unwrap();
        build_streamed_by(lines(0.0), &o, &mut ply, |_| 2000).unwrap();
        drop(ply);
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n.to_string_lossy().starts_with(".u.ply"))
            .collect();
        assert!(!path.exists() && left.is_empty(), "{left:?}");
    }
}
