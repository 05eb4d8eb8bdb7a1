//! VTK pieces shared by the XML and the legacy readers ([`crate::vti`], [`crate::vtk_legacy`]):
//! how a data array becomes fields, and how VTK cell arrays become tetrahedra and hexahedra.

use crate::cfd_grid::Cell;
use crate::{Field, Result, ScalarType, VolumeError};
use std::path::Path;

/// Adds an array as a field: 1 and 3 components as they are, others split per component.
pub(crate) fn push_field(
    fields: &mut Vec<Field>,
    name: String,
    comps: usize,
    ty: ScalarType,
    data: Vec<f32>,
) {
    if comps == 1 || comps == 3 {
        fields.push(Field {
            name,
            components: comps,
            stored: ty,
            data,
        });
    } else {
        for c in 0..comps {
            fields.push(Field {
                name: format!("{name}[{c}]"),
                components: 1,
                stored: ty,
                data: data.iter().skip(c).step_by(comps).copied().collect(),
            });
        }
    }
}

/// Converts VTK cell arrays - connectivity, the end offset of each cell, and VTK cell types -
/// into tetrahedra and hexahedra, with each output cell's source cell index. Cell types:
/// tetrahedra (VTK type 10), hexahedra (12), voxels (11, reordered to hexahedra), wedges (13,
/// split into 3 tetrahedra), pyramids (14, split into 2), and the quadratic tetrahedron and
/// hexahedron (24, 25; their corner nodes). Other cell types are refused.
pub(crate) fn cells_from_vtk(
    path: &Path,
    conn: &[f32],
    offsets: &[f32],
    types: &[f32],
) -> Result<(Vec<Cell>, Vec<usize>)> {
    if offsets.len() != types.len() {
        return Err(VolumeError::format(
            path,
            "Cells offsets",
            format!("{} offsets for {} types", offsets.len(), types.len()),
        ));
    }
    let mut cells = Vec::with_capacity(types.len());
    let mut origin = Vec::with_capacity(types.len());
    let mut start = 0usize;
    for (ci, (&off, &ty)) in offsets.iter().zip(types.iter()).enumerate() {
        let end = off as usize;
        if !(off >= 0.0 && off.fract() == 0.0) || end < start || end > conn.len() {
            return Err(VolumeError::format(
                path,
                "Cells offsets",
                format!(
                    "cell {ci}: offset {off} after {start} (connectivity has {})",
                    conn.len()
                ),
            ));
        }
        // Point ids are whole numbers from 0 (-1, NaN and 1.9 became 0, 0 and 1); the grid's
        // validation checks them against the point count.
        if let Some(&bad) = conn[start..end]
            .iter()
            .find(|&&v| !(v >= 0.0 && v.fract() == 0.0 && v < (1u32 << 31) as f32))
        {
            return Err(VolumeError::format(
                path,
                "Cells connectivity",
                format!("cell {ci}: point id {bad} is not a whole number from 0"),
            ));
        }
        let ids: Vec<u32> = conn[start..end].iter().map(|&v| v as u32).collect();
        start = end;
        let need = match ty as u32 {
            10 | 24 => 4,
            11 | 12 | 25 => 8,
            13 => 6,
            14 => 5,
            t => {
                return Err(VolumeError::format(
                    path,
                    "Cells types",
                    format!("cell {ci} has VTK type {t}; umbra resamples tetrahedra, hexahedra, voxels, wedges and pyramids"),
                ))
            }
        };
        let quadratic = matches!(ty as u32, 24 | 25);
        if ids.len() < need || (!quadratic && ids.len() != need) {
            return Err(VolumeError::format(
                path,
                "Cells connectivity",
                format!("cell {ci} (type {ty}) has {} ids", ids.len()),
            ));
        }
        let i = &ids;
        let mut push = |c: Cell| {
            cells.push(c);
            origin.push(ci);
        };
        match ty as u32 {
            10 | 24 => push(Cell::Tet([i[0], i[1], i[2], i[3]])),
            12 | 25 => push(Cell::Hex([i[0], i[1], i[2], i[3], i[4], i[5], i[6], i[7]])),
            11 => push(Cell::Hex([i[0], i[1], i[3], i[2], i[4], i[5], i[7], i[6]])),
            13 => {
                push(Cell::Tet([i[0], i[1], i[2], i[3]]));
                push(Cell::Tet([i[1], i[2], i[3], i[4]]));
                push(Cell::Tet([i[2], i[3], i[4], i[5]]));
            }
            _ => {
                push(Cell::Tet([i[0], i[1], i[2], i[4]]));
                push(Cell::Tet([i[0], i[2], i[3], i[4]]));
            }
        }
    }
    Ok((cells, origin))
}
