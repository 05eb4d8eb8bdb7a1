//! Slices of volumes (`[[slices]]`): planar polygons drawn in the G-buffer like any surface -
//! they take the tubes' and lines' depth test, cast and receive the volume's and the surfaces'
//! occlusion, and clipping planes cut them - whose colour each fragment samples at its own
//! world position from the layers' grid (`shaders/gbuffer.wgsl`, `plane_color`): the slice's
//! volume through its window and colour map (or label table), then the overlays blended over
//! it in order by their coverage and opacity.
//!
//! All layers of a scene share one grid (the primary volume's: overlays are resampled into it
//! on the CPU, `volume::regrid`), uploaded once as one storage buffer per field. The polygon is
//! an ordinary [`GpuMesh`]: the depth, normal-depth and back-depth passes draw it with the mesh
//! pipelines, and only the colour pass uses the slice entry points (`fs_front_p`,
//! `fs_surface_p`), whose bind group 2 holds the layers.
//!
//! [`plane_color`] is the CPU twin of the shader's colour (tests compare the two per pixel).
//!
//! Index (issue 19; MIP/MinIP have theirs in `occlusion::projection`):
//!
//! | rule | CPU | WGSL | test |
//! |---|---|---|---|
//! | a layer's colour: window `t = (v - lo) / (hi - lo)`, 256-entry map at `255 t`, gaps, labels by the nearest voxel | [`layer_color`] | `gbuffer.wgsl` `plane_layer_color` | `scene/tests/slices_render.rs` `slices_sample_their_layers_exactly` |
//! | a slice: its volume opaque, overlays mixed by coverage x opacity | [`plane_color`] | `gbuffer.wgsl` `plane_color` | the same |
//! | its shading: `lit = false` (default) the colour times the combined occlusion term, marked by G-buffer alpha 0.97 (translucent: a zero normal); `lit` the head light | [`PlaneInput::lit`] | `gbuffer.wgsl` `plane_gcolor`, `fs_peel_p`; `composite.wgsl` (alpha 0.97); `slice_pass.wgsl` `composite_layer` | `slices_sample_their_layers_exactly` (default and lit light), `translucent_slices_over_the_volume_match_the_cpu_twin` |
//! | FXAA leaves pixels wholly on an unlit slice | - | `composite.wgsl` (AOV w), `fxaa.wgsl` `keep` | `slices_sample_their_layers_exactly` (its FXAA case) |
//! | replanning on the same grid (the viewer) | [`GpuPlane::upload_all`] with the kept field buffers; `scene::slices::PlaneModel::replan` | - | `viewer/tests/draw.rs` `slices_moved_hidden_or_restyled_are_replanned_without_a_new_model` |
//! | the polygon: the plane cut by the grid's box | `scene::slices::polygon` | - (a mesh) | `scene::slices` unit test |
//! | crop to slab | `tubes::select::crop` | - | `tubes::select` and `scene::slices` unit tests |
//! | an overlay blended into the volume | `occlusion::emission_absorption::reference_blended` with [`layer_color`] | `slice_pass.wgsl` `blend_color`, `blended` | `an_overlay_blended_into_the_volume_matches_the_cpu_twin` |
//! | translucent layers in depth order, slabs split at them | `occlusion::emission_absorption::reference_with_layers` | `gbuffer.wgsl` `fs_peel`; `slice_pass.wgsl` `march`, `composite_layer` | `translucent_slices_over_the_volume_match_the_cpu_twin` |
//! | colour maps (Moreland 2009 for `cool-warm`) | `volume::colormap::Colormap::rgb` | the 256 entries interpolated as above | `volume::colormap` unit tests |

use crate::gbuffer::GpuMesh;
use crate::gpu::{Gpu, GpuError};
use glam::{DMat4, DVec3, DVec4};
use tubes::tube_mesh::TubeMesh;

/// The most layers (the slice's volume and its overlays) a slice blends.
pub const MAX_LAYERS: usize = 4;

/// The most entries of a label table (labels 0 to 65535).
pub const MAX_LABELS: usize = 65536;

/// How a layer's values become colours.
#[derive(Clone, Debug, PartialEq)]
pub enum LayerMap {
    /// Trilinear samples through a colour map of 256 linear RGB entries over the window
    /// `[lo, hi]` (`t = (v - lo) / (hi - lo)` at position `255 t`, linearly interpolated;
    /// `lo > hi` turns the map round).
    Scalar {
        lo: f64,
        hi: f64,
        colors: Vec<[f32; 3]>,
    },
    /// The nearest voxel's label `l` (rounded) takes `colors[l]` (linear RGB and coverage: 0
    /// hides the label); labels outside the table and NaN are not shown.
    Labels { colors: Vec<[f32; 4]> },
}

/// A layer of a slice: which field of the grid, its mapping and its opacity (overlays).
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneLayer {
    /// Index into [`PlaneGrid::fields`].
    pub field: usize,
    pub map: LayerMap,
    /// The overlay's opacity in [0, 1] (the slice's own volume, layer 0, is opaque).
    pub opacity: f32,
}

/// The grid every slice samples: index-to-world `affine`, `dims`, and the fields (x fastest).
pub struct PlaneGrid<'a> {
    pub dims: [usize; 3],
    pub affine: DMat4,
    pub fields: Vec<&'a [f32]>,
}

/// A slice: its polygon (a mesh whose positions are relative to its origin) and its layers,
/// the first the slice's own volume.
#[derive(Clone, Debug)]
pub struct PlaneInput {
    pub polygon: TubeMesh,
    pub layers: Vec<PlaneLayer>,
    /// Lit by the head light like the other surfaces; else (the default of `[[slices]]`) its
    /// colour unshaded, times the method's combined occlusion term.
    pub lit: bool,
}

/// A slice layer's uniform. Keep in sync with `struct PlaneLayer` in `shaders/gbuffer.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PlaneLayerParams {
    pub lo: f32,
    pub hi: f32,
    pub opacity: f32,
    /// 1: a label layer.
    pub labels: u32,
    /// The layer's first entry in the colour table.
    pub lut: u32,
    /// Label layers: entries in the table.
    pub count: u32,
    /// 1: the slice's own volume.
    pub base: u32,
    pub pad: u32,
}

/// A slice's uniform. Keep in sync with `struct PlaneParams` in `shaders/gbuffer.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PlaneParams {
    /// Camera-relative position to voxel index.
    pub rel_to_index: [[f32; 4]; 4],
    /// Samples per axis and the number of layers.
    pub dims: [u32; 4],
    /// x: 1 when the slice is lit by the head light (yzw: padding).
    pub shading: [u32; 4],
    pub layers: [PlaneLayerParams; MAX_LAYERS],
}

/// A slice on the GPU: its polygon, its colour table and its layers' fields.
#[derive(Clone)]
pub struct GpuPlane {
    pub(crate) mesh: GpuMesh,
    pub(crate) lut: wgpu::Buffer,
    /// The layers' field buffers, in layer order (the first repeated up to [`MAX_LAYERS`]).
    pub(crate) fields: Vec<wgpu::Buffer>,
    layers: [PlaneLayerParams; MAX_LAYERS],
    n_layers: u32,
    lit: bool,
    dims: [usize; 3],
    world_to_index: DMat4,
}

/// Checks a slice's layers against the grid: an error names the slice (`what`) and the layer.
fn check(grid: &PlaneGrid, p: &PlaneInput, what: &str) -> Result<(), String> {
    if p.layers.is_empty() || p.layers.len() > MAX_LAYERS {
        return Err(format!(
            "{what}: {} layers; a slice shows its volume and at most {} overlays",
            p.layers.len(),
            MAX_LAYERS - 1
        ));
    }
    for (i, l) in p.layers.iter().enumerate() {
        check_layer(grid, l, &format!("{what}: layer {i}"))?;
    }
    Ok(())
}

/// Checks one layer against the grid (its field's length, a 256-entry colour map and a finite
/// window of non-zero width in f32, a label table of 1 to [`MAX_LABELS`] entries, an opacity in
/// [0, 1]); `what` names it in the error.
pub fn check_layer(grid: &PlaneGrid, l: &PlaneLayer, what: &str) -> Result<(), String> {
    let n: usize = grid.dims.iter().product();
    let Some(f) = grid.fields.get(l.field) else {
        return Err(format!(
            "{what} names field {} of {}",
            l.field,
            grid.fields.len()
        ));
    };
    if f.len() != n {
        return Err(format!("{what} has {} samples, the grid {n}", f.len()));
    }
    match &l.map {
        LayerMap::Scalar { lo, hi, colors } => {
            let (a, b) = (*lo as f32, *hi as f32);
            if colors.len() != 256
                || !(a.is_finite() && b.is_finite() && (b - a).is_finite())
                || a == b
            {
                return Err(format!(
                    "{what}: the colour map needs 256 entries and a finite window of non-zero width"
                ));
            }
        }
        LayerMap::Labels { colors } => {
            if colors.is_empty() || colors.len() > MAX_LABELS {
                return Err(format!(
                    "{what}: a label table of {} entries (1 to {MAX_LABELS})",
                    colors.len()
                ));
            }
        }
    }
    if !(0.0..=1.0).contains(&l.opacity) {
        return Err(format!("{what}: opacity {} is not in [0, 1]", l.opacity));
    }
    Ok(())
}

impl GpuPlane {
    /// Uploads the slices of one grid; the grid's fields are uploaded once and shared, and
    /// kept in `buffers` (by field index): a field already there is not uploaded again, so
    /// slices planned anew on the same grid upload only their polygons and tables. `buffers`
    /// must hold nothing but this grid's fields.
    pub fn upload_all(
        gpu: &Gpu,
        grid: &PlaneGrid,
        planes: &[PlaneInput],
        buffers: &mut Vec<Option<wgpu::Buffer>>,
    ) -> Result<Vec<GpuPlane>, GpuError> {
        if planes.is_empty() {
            return Ok(vec![]);
        }
        for (k, p) in planes.iter().enumerate() {
            check(grid, p, &format!("slice {k}")).map_err(GpuError::Operation)?;
        }
        let storage = wgpu::BufferUsages::STORAGE;
        buffers.resize(grid.fields.len(), None);
        let world_to_index = grid.affine.inverse();
        let mut out = vec![];
        for p in planes {
            let mut fields = vec![];
            for l in &p.layers {
                if buffers[l.field].is_none() {
                    let f = grid.fields[l.field];
                    gpu.check_buffer("slice layer", f.len() as u64 * 4, storage)?;
                    // NaN as the passes' gap value (shaders compiled with fast maths may not
                    // see NaN).
                    let f = occlusion::emission_absorption::prepare(f);
                    buffers[l.field] =
                        Some(gpu.buffer("slice layer", bytemuck::cast_slice(&f), storage));
                }
                fields.push(buffers[l.field].clone().expect("uploaded above"));
            }
            while fields.len() < MAX_LAYERS {
                fields.push(fields[0].clone());
            }
            let mut lut: Vec<[f32; 4]> = vec![];
            let mut layers = [PlaneLayerParams::default(); MAX_LAYERS];
            for (i, l) in p.layers.iter().enumerate() {
                let start = lut.len() as u32;
                let (lo, hi, labels, count) = match &l.map {
                    LayerMap::Scalar { lo, hi, colors } => {
                        lut.extend(colors.iter().map(|c| [c[0], c[1], c[2], 1.0]));
                        (*lo as f32, *hi as f32, 0, 256)
                    }
                    LayerMap::Labels { colors } => {
                        lut.extend(colors.iter().copied());
                        (0.0, 1.0, 1, colors.len() as u32)
                    }
                };
                layers[i] = PlaneLayerParams {
                    lo,
                    hi,
                    opacity: l.opacity,
                    labels,
                    lut: start,
                    count,
                    base: (i == 0) as u32,
                    pad: 0,
                };
            }
            gpu.check_buffer("slice colour table", lut.len() as u64 * 16, storage)?;
            let Some(mesh) = GpuMesh::upload(gpu, &p.polygon)? else {
                continue;
            };
            out.push(GpuPlane {
                mesh,
                lut: gpu.buffer("slice colour table", bytemuck::cast_slice(&lut), storage),
                fields,
                layers,
                n_layers: p.layers.len() as u32,
                lit: p.lit,
                dims: grid.dims,
                world_to_index,
            });
        }
        Ok(out)
    }

    /// The slice's uniform for a camera at `eye`.
    pub(crate) fn params(&self, eye: DVec3) -> PlaneParams {
        let m = self.world_to_index * DMat4::from_translation(eye);
        PlaneParams {
            rel_to_index: crate::prelude::mat4(m),
            dims: [
                self.dims[0] as u32,
                self.dims[1] as u32,
                self.dims[2] as u32,
                self.n_layers,
            ],
            shading: [self.lit as u32, 0, 0, 0],
            layers: self.layers,
        }
    }
}

/// A layer's colour (linear RGB) and coverage at world point `p` of `grid`, as the shaders map
/// it (`plane_layer_color` in `gbuffer.wgsl`, `blend_color` in `slice_pass.wgsl`): `base`
/// for a slice's own volume (opaque, the window clamped, gaps at its low end), else an overlay
/// (nothing where `t <= 0` or a gap). Samples are taken at `p`'s voxel index clamped into the
/// grid: trilinear, or the nearest voxel for labels. `l` must be a layer [`check_layer`]
/// accepts (as every uploaded one is).
pub fn layer_color(grid: &PlaneGrid, l: &PlaneLayer, p: DVec3, base: bool) -> ([f64; 3], f64) {
    let q = (grid.affine.inverse() * DVec4::from((p, 1.0))).truncate();
    let d = grid.dims;
    let hi = DVec3::new(d[0] as f64 - 1.0, d[1] as f64 - 1.0, d[2] as f64 - 1.0);
    let c = q.clamp(DVec3::ZERO, hi);
    let f = grid.fields[l.field];
    match &l.map {
        LayerMap::Labels { colors } => {
            let i = [0, 1, 2].map(|k| (c[k] + 0.5).floor() as usize);
            let v = f[i[0] + d[0] * (i[1] + d[1] * i[2])] as f64;
            if v.is_finite() && v >= 0.0 && v < colors.len() as f64 {
                let e = colors[((v + 0.5).floor() as usize).min(colors.len() - 1)];
                ([e[0] as f64, e[1] as f64, e[2] as f64], e[3] as f64)
            } else {
                ([0.0; 3], 0.0)
            }
        }
        LayerMap::Scalar { lo, hi, colors } => {
            let prepared = occlusion::emission_absorption::prepare(f);
            let v = occlusion::emission_absorption::sample(&prepared, d, c).unwrap_or(-3e38);
            let gap = v < -1e30;
            let mut t = (v - lo) / (hi - lo);
            let shown = if base {
                t = if gap { 0.0 } else { t.clamp(0.0, 1.0) };
                true
            } else {
                !gap && t > 0.0
            };
            if !shown {
                return ([0.0; 3], 0.0);
            }
            let x = t.min(1.0) * 255.0;
            let i = (x.floor() as usize).min(254);
            let (a, b) = (colors[i], colors[i + 1]);
            let u = x - i as f64;
            (
                [0, 1, 2].map(|k| a[k] as f64 + (b[k] as f64 - a[k] as f64) * u),
                1.0,
            )
        }
    }
}

/// The CPU twin of the shader's slice colour at world point `p` (linear RGB): the layers'
/// samples at `p`'s voxel index, mapped and blended as `plane_color` does, in f64. NaN and
/// infinite samples (and trilinear samples next to one) are gaps: the slice's volume shows its
/// map's low end there, an overlay nothing.
pub fn plane_color(grid: &PlaneGrid, layers: &[PlaneLayer], p: DVec3) -> [f64; 3] {
    let mut out = [0.0f64; 3];
    for (li, l) in layers.iter().enumerate() {
        let (rgb, a) = layer_color(grid, l, p, li == 0);
        if li == 0 {
            out = rgb.map(|x| x * a);
        } else {
            let w = a * l.opacity as f64;
            out = [0, 1, 2].map(|k| out[k] + (rgb[k] - out[k]) * w);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_uniforms_match_their_wgsl_structs() {
        crate::prelude::assert_layout!(
            crate::gbuffer::SHADER,
            "PlaneLayer",
            super::PlaneLayerParams {
                lo,
                hi,
                opacity,
                labels,
                lut,
                count,
                base,
                pad,
            }
        );
        crate::prelude::assert_layout!(
            crate::gbuffer::SHADER,
            "PlaneParams",
            super::PlaneParams {
                rel_to_index,
                dims,
                shading,
                layers,
            }
        );
    }
}
