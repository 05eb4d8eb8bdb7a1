//! The native CPU renderer: for machines without a GPU, where Mesa's lavapipe runs the
//! renderer's compute passes several times slower than a ray caster written for the CPU
//! (docs/benchmarks.md, "Renderer speed"). It renders the same model as the GPU passes and
//! their f64 CPU twins - emission-absorption through view-aligned slices,
//! `occlusion::emission_absorption` - so it is chosen by `render.device` without changing
//! the image beyond f32 rounding (tested against the twin).
//!
//! What makes it fast, per ray: the samples lie where the ray crosses the slice planes, so
//! their index-space positions are `q_k = q_a + k dq` (no matrix per sample); the slices
//! where the ray is inside the grid are solved for once; empty blocks of 4^3 cells
//! (`occlusion::emission_absorption::occupancy_of`) are stepped over whole, to the first
//! slice past the block, instead of sample by sample; rays end when the opacity passes `OPAQUE`
//! (as the shader); the samples are read in their stored type (`volume::samples`:
//! `u8`/`u16` plus an offset, or `f32`), from a copy in bricks of that type where it is small
//! ([`EaVolume::shared`]), else where the model keeps them (shared, not copied); rays
//! march in packets of 4 x 4; the transfer function is evaluated exactly (piecewise linear,
//! not a table) and the exponential from a table (within 8e-6); bands of rows run on rayon's
//! threads, compiled for AVX2 and FMA where the CPU has them, where the `ea` march (unlit, or
//! lit by the light volume) and the projections' take eight rays of a packet at a time in AVX2
//! lanes (`lanes`, bit for bit the scalar march) and four pixels' rays are set up at once.
//!
//! Scope: volume-only scenes with 1-D transfer functions and clipping planes: `ea` (unshaded
//! emission-absorption), with a light volume ([`light`]: Schott et al.'s occlusion buffer on
//! cells, as the GPU's `light` pass) `dos` and `combined`, and the projections `mip` and
//! `minip` ([`EaVolume::render_projection`], the model of `occlusion::projection`). Phong
//! shading, 2-D transfer functions, geometry and isosurfaces are drawn on the GPU.

use glam::{DMat3, DMat4, DVec3, DVec4};
use occlusion::emission_absorption::{
    clip_interval, occupancy_packed, prepare, slab_interval, EaView, Transfer, BRICK,
};
use occlusion::projection::Extremum;
use rayon::prelude::*;
use std::sync::Arc;
use volume::samples::{Packing, Sample as Voxel, Samples, View};

#[cfg(target_arch = "x86_64")]
mod lanes;
mod light;
pub use light::LightSettings;
use light::{Footprint, LightVolume};

/// A frame of the CPU renderer: the image (as [`EaVolume::render`]), per pixel the volume's
/// opacity-weighted mean occlusion (`occlusion.volumetric`: 1 where the volume is not lit or
/// not there) and the view depth where its opacity passed 0.5 (0: never), and the time the
/// light volume took (0 without one).
pub struct Frame {
    pub image: Vec<[f32; 4]>,
    pub volumetric: Vec<f32>,
    pub half_depth: Vec<f32>,
    pub light_ms: f64,
}

/// The ray through a continuous pixel position `px` (y down) of view `v`, as the shaders'
/// `pixel_ray`: from the near plane, unit direction.
#[inline(always)]
pub(crate) fn pixel_ray(inv: &DMat4, v: &EaView, px: [f64; 2]) -> (DVec3, DVec3) {
    let ndc_x = 2.0 * px[0] / v.width as f64 - 1.0;
    let ndc_y = 1.0 - 2.0 * px[1] / v.height as f64;
    let un = |z: f64| {
        let p = *inv * DVec4::new(ndc_x, ndc_y, z, 1.0);
        p.truncate() / p.w
    };
    let (a, b) = (un(0.0), un(1.0));
    (a, (b - a).normalize())
}

/// A volume ready to ray cast: its samples as the passes read them (NaN as a gap), its grid,
/// its empty-space blocks and its transfer function.
pub struct EaVolume {
    dims: [usize; 3],
    /// The samples: in bricks (`bricks` `Some`: a copy in the samples' own type), or x
    /// fastest (`None`: shared with the model that holds them).
    data: Arc<Samples>,
    /// What is added to a stored sample to give its value (`Packing::offset`).
    offset: f32,
    /// Offsets of a cell's eight corners from its first, x fastest, then y, then z, in the
    /// whole grid's layout (`bricks` `None`).
    corner: [usize; 8],
    /// The layout of `data`: bricks of `BRICK^3` cells per axis, each `APRON^3` samples with
    /// its far faces so that a cell's corners are in one brick (`Some`: a copy the volume
    /// made, read 20-25% faster than the grid's layout on the MNI T1), or the grid's own
    /// layout, x fastest (`None`: the model's samples, shared).
    bricks: Option<[usize; 3]>,
    world_to_index: DMat4,
    /// Blocks of `SKIP^3` cells per axis, and whether each has extinction anywhere
    /// (`occupancy_of`): the empty ones are stepped over.
    blocks: [usize; 3],
    occupied: Vec<bool>,
    /// The indices of the occupied blocks (`light::EaVolume::steps_occupied`).
    occupied_blocks: Vec<u32>,
    /// Per block, its Chebyshev distance in blocks to the nearest occupied one (0: occupied;
    /// at most [`REACH`]): a ray in an empty block may step over the whole cube of blocks
    /// around it that this distance leaves empty.
    reach: Vec<u8>,
    /// [`EaVolume::reach`] widened to 32 bits, for the gathers of `lanes`.
    reach32: Vec<i32>,
    /// Whether `ea` frames (unlit, or lit by the light volume) march eight rays at a time
    /// where the CPU can (`lanes`; on by default, off to compare with the scalar march).
    lanes: bool,
    /// Whether clipped rays sample the slabs wholly behind the planes as without them
    /// ([`EaVolume::clip_slabs`]; off only in tests: every slab cut slab by slab).
    clip_slabs: bool,
    /// Whether the light sweep samples a cell only in the steps an occupied block's box
    /// reaches (`light::EaVolume::steps_occupied`; off only in tests: the same light).
    step_mask: bool,
    tf: Vec<(f32, [f32; 3], f32)>,
    /// Per point `i > 0`: the segment from point `i - 1` as `1 / (v_i - v_{i-1})` (0 for a
    /// step) and the colour and extinction differences (no division per sample).
    slopes: Vec<(f32, [f32; 3], f32)>,
    /// The last index per axis.
    hi: [f32; 3],
    /// `exp(-x)` at `x = i / EXP_SCALE` (see [`EaVolume::exp_neg`]).
    exp_table: Vec<f32>,
    /// `f32` samples in `u8` or `u16` where they are integers from 0 to 255 or 65,535
    /// (`None`: they are not, or they are stored narrow already), made at the first lit frame
    /// for the light sweep.
    sweep_samples: std::sync::OnceLock<Option<Samples>>,
    /// The last frame's light volume, kept for the next (`light::LightVolume`): tens of
    /// megabytes a frame allocated afresh cost their page faults and a fill every frame.
    light_store: std::sync::Mutex<Vec<f32>>,
    /// The transfer function is transparent below its values (its first point has no
    /// extinction) rather than above them: which side of the extreme empty blocks lie on.
    clear_below: bool,
}

impl EaVolume {
    /// Prepares `data` (the field of `vol`, x fastest) with the transfer function `tf`;
    /// errors for what only the GPU draws (a 2-D transfer function) and for a grid whose
    /// sample count does not match. The samples are kept as `f32` up to [`NARROW_ABOVE`]
    /// bytes of them, beyond it in the narrowest type that holds them exactly (see
    /// [`EaVolume::storage`]).
    pub fn new(vol: &volume::Volume, data: &[f32], tf: &Transfer) -> Result<EaVolume, String> {
        let narrow = data.len() * 4 > NARROW_ABOVE;
        EaVolume::with_storage(vol, data, tf, narrow)
    }

    /// [`EaVolume::new`] with the storage chosen: `narrow` keeps integer data in `u8` or
    /// `u16` (plus an offset), else `f32`.
    pub fn with_storage(
        vol: &volume::Volume,
        data: &[f32],
        tf: &Transfer,
        narrow: bool,
    ) -> Result<EaVolume, String> {
        let data = prepare(data);
        let packing = match narrow {
            true => Packing::of(&data),
            false => Packing::F32,
        };
        EaVolume::build(vol, Arc::new(Samples::f32(data)), tf, Some(packing))
    }

    /// A volume reading the packed samples `data` of `vol` (as `emission_absorption::prepare`
    /// leaves them: gaps below -1e30): where a copy of them in bricks, in their own packing
    /// (`u8`, `u16` or `f32`), would take at most [`COPY_AT_MOST`] bytes the volume keeps one,
    /// which frames read fastest (the grid's layout costs 20-35% a frame; since a cell's
    /// corners along x come in one gather element, `u8` bricks are read faster than `f32`
    /// ones: docs/benchmarks.md); larger volumes are read where they are, shared and not
    /// copied, in their stored type and the grid's layout - rendering then holds no more
    /// than the model's samples.
    pub fn shared(
        vol: &volume::Volume,
        data: Arc<Samples>,
        tf: &Transfer,
    ) -> Result<EaVolume, String> {
        let bytes = match data.packing() {
            Packing::U8 { .. } => 1.0,
            Packing::U16 { .. } => 2.0,
            Packing::F32 => 4.0,
        };
        let bricks = data.len() as f64 * bytes * (APRON as f64 / BRICK as f64).powi(3);
        let copy = (bricks <= COPY_AT_MOST as f64).then_some(data.packing());
        EaVolume::build(vol, data, tf, copy)
    }

    /// [`EaVolume::shared`] that always reads the samples where they are (no copy at any
    /// size).
    pub fn in_place(
        vol: &volume::Volume,
        data: Arc<Samples>,
        tf: &Transfer,
    ) -> Result<EaVolume, String> {
        EaVolume::build(vol, data, tf, None)
    }

    /// The volume of samples `data` on `vol`'s grid (x fastest), read where they are
    /// (`bricked` `None`) or from a copy in bricks packed as `bricked`.
    fn build(
        vol: &volume::Volume,
        data: Arc<Samples>,
        tf: &Transfer,
        bricked_as: Option<Packing>,
    ) -> Result<EaVolume, String> {
        if !tf.rows.is_empty() {
            return Err(
                "a 2-D transfer function (gradient rows) is drawn by the GPU passes only".into(),
            );
        }
        let n = vol.dims.iter().product::<usize>();
        if data.len() != n || n == 0 {
            return Err(format!(
                "the field has {} samples for a {} x {} x {} grid",
                data.len(),
                vol.dims[0],
                vol.dims[1],
                vol.dims[2]
            ));
        }
        let (blocks, occ) = occupancy_packed(&data, vol.dims, tf, SKIP);
        let (data, bricks) = match bricked_as {
            Some(packing) => {
                let bricks = vol.dims.map(|d| d.saturating_sub(1).max(1).div_ceil(BRICK));
                (
                    Arc::new(bricks_of(&data, vol.dims, bricks, packing)),
                    Some(bricks),
                )
            }
            None => (data, None),
        };
        let points: Vec<(f32, [f32; 3], f32)> = tf
            .points
            .iter()
            .map(|(v, c, e)| {
                let e = if e.is_finite() { e.max(0.0) } else { 0.0 };
                // Finite in f32 too (a value or extinction beyond f32's range would give
                // NaN slopes).
                let f = |x: f64| (x as f32).clamp(-f32::MAX, f32::MAX);
                (f(*v), c.map(f), f(e))
            })
            .collect();
        let slopes = (0..points.len())
            .map(|i| {
                let (a, b) = (points[i.saturating_sub(1)], points[i]);
                let w = b.0 - a.0;
                let inv = if w > 0.0 { 1.0 / w } else { 0.0 };
                (inv, [0, 1, 2].map(|k| b.1[k] - a.1[k]), b.2 - a.2)
            })
            .collect();
        // An axis of one sample has one corner along it (offset 0), as the bricks repeat
        // their last sample.
        let [nx, ny, nz] = vol.dims;
        let sx = (nx > 1) as usize;
        let sy = if ny > 1 { nx } else { 0 };
        let sz = if nz > 1 { nx * ny } else { 0 };
        Ok(EaVolume {
            dims: vol.dims,
            offset: data.packing().offset(),
            data,
            corner: [0, sx, sy, sy + sx, sz, sz + sx, sz + sy, sz + sy + sx],
            bricks,
            world_to_index: vol.affine.inverse(),
            blocks,
            occupied: occ.iter().map(|&o| o != 0).collect(),
            occupied_blocks: (0..occ.len() as u32)
                .filter(|&b| occ[b as usize] != 0)
                .collect(),
            reach: reach_of(&occ, blocks),
            reach32: reach_of(&occ, blocks).into_iter().map(i32::from).collect(),
            lanes: true,
            clip_slabs: true,
            step_mask: true,
            slopes,
            hi: vol.dims.map(|n| n as f32 - 1.0),
            sweep_samples: std::sync::OnceLock::new(),
            light_store: std::sync::Mutex::new(Vec::new()),
            clear_below: points.first().is_none_or(|p| p.2 <= 0.0),
            tf: points,
            exp_table: (0..=EXP_N + 1)
                .map(|i| (-(i as f64) / EXP_SCALE as f64).exp() as f32)
                .collect(),
        })
    }

    /// Colour and extinction at `v` (piecewise linear, constant beyond the ends): the f32 twin
    /// of `occlusion::emission_absorption::Transfer::eval` with the segments' slopes
    /// precomputed (the f64 one divides per call).
    #[inline(always)]
    fn transfer(&self, v: f32) -> ([f32; 3], f32) {
        let p = &self.tf;
        let Some(first) = p.first() else {
            return ([0.0; 3], 0.0);
        };
        if v <= first.0 {
            return (first.1, first.2);
        }
        for i in 1..p.len() {
            if v <= p[i].0 {
                let (a, (inv, dc, de)) = (&p[i - 1], self.slopes[i]);
                let t = (v - a.0) * inv;
                let c = [0, 1, 2].map(|k| a.1[k] + dc[k] * t);
                return (c, a.2 + de * t);
            }
        }
        let l = p[p.len() - 1];
        (l.1, l.2)
    }

    /// How the samples are stored: `u8`, `u16` (data whose every value is an integer in
    /// their range, e.g. a uint8 MRI: 4 or 2 times less memory, the same values) or `f32`.
    /// Measured once one corner took a gather element (`examples/storage.rs`, MNI T1 and
    /// headsq at 512^2): the narrow types cost 5-8% more time a frame (the conversion to
    /// float per corner); since a cell's corners along x share one, `u8` bricks of the MNI T1
    /// draw 8-20% faster than `f32` ones (docs/benchmarks.md, "Packets with nothing to do"),
    /// so [`EaVolume::shared`] keeps the samples' own type.
    pub fn storage(&self) -> &'static str {
        match self.data.packing() {
            Packing::U8 { .. } => "u8",
            Packing::U16 { .. } => "u16",
            Packing::F32 => "f32",
        }
    }

    /// The eight corners of cell `c` as stored (add [`EaVolume::offset`] for values): x
    /// fastest, then y, then z. Below -1e30 next to a gap.
    #[inline(always)]
    fn corners<T: Voxel>(&self, d: &[T], c: [usize; 3]) -> [f32; 8] {
        let [cx, cy, cz] = c;
        let Some(bricks) = self.bricks else {
            let i = cx + self.dims[0] * (cy + self.dims[1] * cz);
            // One bounds check for the cell's last corner; the others are below it.
            let d = &d[i..=i + self.corner[7]];
            return self.corner.map(|o| d[o].value());
        };
        let brick = cx / BRICK + bricks[0] * (cy / BRICK + bricks[1] * (cz / BRICK));
        // One bounds check for the brick; the corners' offsets within it are below APRON^3
        // by construction (local cells 0..BRICK), which the compiler sees.
        let d = &d[brick * APRON.pow(3)..][..APRON.pow(3)];
        let i = cx % BRICK + APRON * (cy % BRICK + APRON * (cz % BRICK));
        let (sy, sz) = (APRON, APRON * APRON);
        [
            d[i].value(),
            d[i + 1].value(),
            d[i + sy].value(),
            d[i + sy + 1].value(),
            d[i + sz].value(),
            d[i + sz + 1].value(),
            d[i + sz + sy].value(),
            d[i + sz + sy + 1].value(),
        ]
    }

    /// Trilinear interpolation of a cell's corners at the position `f` in it.
    #[inline(always)]
    fn trilinear(v: &[f32; 8], f: [f32; 3]) -> f32 {
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let x00 = lerp(v[0], v[1], f[0]);
        let x10 = lerp(v[2], v[3], f[0]);
        let x01 = lerp(v[4], v[5], f[0]);
        let x11 = lerp(v[6], v[7], f[0]);
        lerp(lerp(x00, x10, f[1]), lerp(x01, x11, f[1]), f[2])
    }

    /// The cell holding `q` (inside the grid; the last cell for the far faces), and its skip
    /// block's index and per-axis position.
    #[inline(always)]
    fn cell(&self, q: [f32; 3]) -> ([usize; 3], usize, [usize; 3]) {
        // Through u32: `f32 as usize` (saturating) is a dozen instructions on x86-64 per axis
        // and sample, `as u32` about four (`perf annotate` of the march).
        let c = [0, 1, 2].map(|a| (q[a] as u32 as usize).min(self.dims[a].max(2) - 2));
        let s = c.map(|x| x / SKIP);
        let j = s[0] + self.blocks[0] * (s[1] + self.blocks[1] * s[2]);
        (c, j, s)
    }

    /// The image of `v` (rows top to bottom): RGBA with the background composited under the
    /// volume and alpha its opacity, as `occlusion::emission_absorption::reference`.
    pub fn render(&self, v: &EaView) -> Vec<[f32; 4]> {
        self.render_frame(v, None).image
    }

    /// A frame of `v`: emission-absorption, and with `light` its colour times the light
    /// volume's `O` (the `dos` and `combined` methods on a volume-only scene; [`light`]).
    /// Rays are marched in packets of `TILE x TILE` pixels, a step of each in turn, so that
    /// neighbouring rays read the voxels their neighbours just brought into the cache.
    pub fn render_frame(&self, v: &EaView, light: Option<&LightSettings>) -> Frame {
        match self.data.view() {
            View::U8(d, _) => self.render_with(v, d, light, 0),
            View::U16(d, _) => self.render_with(v, d, light, 0),
            View::F32(d) => self.render_with(v, d, light, 0),
        }
    }

    /// A frame of the projection `which` (`mip`, `minip`; `occlusion::projection`): the
    /// extreme sample along each ray (the slices' samples, clipping planes applied) through
    /// the transfer function, premultiplied over the background. Empty blocks (every value
    /// they span transparent) are stepped over where the transparent side is away from the
    /// extreme, and end the ray transparent where it is towards it: the same image as taking
    /// every sample.
    pub fn render_projection(&self, v: &EaView, which: Extremum) -> Frame {
        let mode = match which {
            Extremum::Max => 1,
            Extremum::Min => 2,
        };
        match self.data.view() {
            View::U8(d, _) => self.render_with(v, d, None, mode),
            View::U16(d, _) => self.render_with(v, d, None, mode),
            View::F32(d) => self.render_with(v, d, None, mode),
        }
    }

    /// A frame, drawn in a worker thread of rayon's pool: the light sweep's slices are shared
    /// by the caller and the pool's idle workers (`light::sweep_slices`), and the eye's rays
    /// are a parallel loop. From a thread outside the pool, each parallel loop had been a job
    /// handed over and a sleep on a latch until a worker finished it (perf, 128 x 128
    /// `combined` with one worker, when the sweep forked and joined per slice: a third of the
    /// frame in the scheduler).
    fn render_with<T: Voxel>(
        &self,
        v: &EaView,
        data: &[T],
        light: Option<&LightSettings>,
        mode: u8,
    ) -> Frame {
        // The sweep's narrowed samples made out here: made inside, by a parallel loop, the
        // worker waiting in `get_or_init` could steal another frame of this volume and wait
        // on the same cell again.
        if light.is_some() {
            self.sweep_samples.get_or_init(|| narrowed(&self.data));
        }
        rayon::scope(|_| self.render_in_pool(v, data, light, mode))
    }

    fn render_in_pool<T: Voxel>(
        &self,
        v: &EaView,
        data: &[T],
        light: Option<&LightSettings>,
        mode: u8,
    ) -> Frame {
        let (w, h) = (v.width as usize, v.height as usize);
        let mut out = vec![Pixel::default(); w * h];
        if w == 0 || h == 0 {
            return Frame {
                image: vec![],
                volumetric: vec![],
                half_depth: vec![],
                light_ms: 0.0,
            };
        }
        let aspect = w as f64 / h as f64;
        let inv = v.camera.view_projection(aspect).inverse();
        let bg = v.background.map(|x| x as f32);
        let t = std::time::Instant::now();
        // The sweep samples a plane of the volume a slice, all of it each time: where the
        // samples are integers it reads them in their narrow type, 2-4 times fewer bytes
        // (the same values; measured: the sweep is bound by the plane's cache misses).
        let lv = light.map(
            |s| match self.sweep_samples.get_or_init(|| narrowed(&self.data)) {
                Some(n) => match n.view() {
                    View::U8(d, _) => self.sweep(v, d, s, inv),
                    View::U16(d, _) => self.sweep(v, d, s, inv),
                    View::F32(d) => self.sweep(v, d, s, inv),
                },
                None => self.sweep(v, data, s, inv),
            },
        );
        let light_ms = if lv.is_some() {
            t.elapsed().as_secs_f64() * 1e3
        } else {
            0.0
        };
        // Behind clipping planes, where the light cells' rays enter the kept depths.
        let entries = match &lv {
            Some(lv) if !v.clip.is_empty() => lv.clip_entries(v, |p| pixel_ray(&inv, v, p)),
            _ => vec![],
        };
        #[cfg(target_arch = "x86_64")]
        let fma = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
        out.par_chunks_mut(w * TILE)
            .enumerate()
            .for_each(|(band, rows)| {
                let job = Band {
                    v,
                    data,
                    inv,
                    bg,
                    band,
                    rows,
                    light: lv.as_ref(),
                    entries: &entries,
                    mode,
                    simd: false,
                };
                #[cfg(target_arch = "x86_64")]
                if fma {
                    let job = Band { simd: true, ..job };
                    // SAFETY: the CPU has AVX2 and FMA (checked above).
                    unsafe { self.band_fma(job) };
                    return;
                }
                self.band(job);
            });
        if let Some(lv) = lv {
            self.keep_light(lv);
        }
        Frame {
            image: out.iter().map(|p| p.rgba).collect(),
            volumetric: out.iter().map(|p| p.volumetric).collect(),
            half_depth: out.iter().map(|p| p.half).collect(),
            light_ms,
        }
    }

    /// [`EaVolume::band`] compiled for AVX2 and FMA, chosen at run time where the CPU has
    /// them (Rust fuses no multiply-add on its own, so the arithmetic is the plain one's; the
    /// packets may go to `lanes`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn band_fma<T: Voxel>(&self, job: Band<'_, T>) {
        self.band(job)
    }

    /// One band of `TILE` rows of the image: its packets of rays, marched and composited.
    #[inline(always)]
    fn band<T: Voxel>(&self, job: Band<'_, T>) {
        // Never read: the march without light does not look the light up.
        let none = LightVolume::empty();
        match (job.light, job.mode) {
            (Some(lv), _) => self.band_with::<T, true, 0>(job, lv),
            (None, 1) => self.band_with::<T, false, 1>(job, &none),
            (None, 2) => self.band_with::<T, false, 2>(job, &none),
            (None, _) => self.band_with::<T, false, 0>(job, &none),
        }
    }

    #[inline(always)]
    fn band_with<T: Voxel, const LIT: bool, const MODE: u8>(
        &self,
        job: Band<'_, T>,
        lv: &LightVolume,
    ) {
        let Band {
            v,
            data,
            inv,
            bg,
            band,
            rows,
            simd,
            entries,
            ..
        } = job;
        let w = v.width as usize;
        let y0 = band * TILE;
        let nrows = rows.len() / w;
        // Made once a band: the view's direction, the tiles' rays, the lanes' constants.
        let forward = v.camera.forward();
        let mut rays: Vec<(usize, Ray)> = Vec::with_capacity(TILE * TILE);
        #[cfg(target_arch = "x86_64")]
        let splat = (simd
            && if v.clip.is_empty() {
                self.lanes_apply(v, data, LIT.then_some(lv))
            } else {
                // Clipped: the slabs behind the planes (`EaVolume::march_clipped`).
                self.clip_slabs && self.lanes_apply_planes(v, data, LIT.then_some(lv))
            })
        // SAFETY: `simd` is set only where the CPU has AVX2 and FMA.
        .then(|| unsafe { lanes::Splat::new(self) });
        for x0 in (0..w).step_by(TILE) {
            rays.clear();
            for dy in 0..nrows {
                let y = (y0 + dy) as f64 + 0.5;
                let first = rays.len();
                // A row of four pixels' rays at once where the CPU has AVX2 and FMA (and the
                // lanes are on: off, the frame is the scalar code's throughout).
                #[cfg(target_arch = "x86_64")]
                if simd && self.lanes && x0 + TILE <= w {
                    const { assert!(TILE == 4) };
                    let xs = [0.5, 1.5, 2.5, 3.5].map(|i| x0 as f64 + i);
                    // SAFETY: `simd` is set only where the CPU has AVX2 and FMA.
                    unsafe { self.rays4(v, &inv, forward, xs, y, &mut rays, x0 + w * dy) };
                }
                if rays.len() == first {
                    for x in x0..(x0 + TILE).min(w) {
                        let (o, d) = pixel_ray(&inv, v, [x as f64 + 0.5, y]);
                        rays.push((x + w * dy, self.start_along(v, forward, o, d)));
                    }
                }
                if !v.clip.is_empty() && self.clip_slabs {
                    for (_, r) in rays[first..].iter_mut() {
                        self.clip_slabs(v, r);
                    }
                }
                if LIT {
                    for (i, r) in rays[first..].iter_mut() {
                        let px = [(*i % w) as f64 + 0.5, y];
                        r.light = lv.footprint(px);
                        if !v.clip.is_empty() {
                            let entry = occlusion::emission_absorption::clip_entry(v, r.o, r.d);
                            lv.clip_shifts(&mut r.light, px, v, entry, entries);
                        }
                    }
                }
            }
            let mut live = true;
            #[cfg(target_arch = "x86_64")]
            if let Some(splat) = &splat {
                // SAFETY: `splat` is made only where the CPU has AVX2 and FMA and
                // `lanes_apply` holds for the volume, the view and the light volume.
                live = !unsafe {
                    if !v.clip.is_empty() {
                        self.march_clipped::<T, LIT, MODE>(splat, v, data, lv, &mut rays)
                    } else if MODE == 0 {
                        self.march_lanes::<T, LIT>(splat, v, data, lv, &mut rays)
                    } else {
                        self.march_lanes_extreme::<T, MODE>(splat, data, &mut rays)
                    }
                };
            }
            // March together, a step of each ray a turn (neighbours stay near each other in
            // depth as long as they skip alike).
            while live {
                live = false;
                for (_, r) in rays.iter_mut() {
                    if r.next().is_some() {
                        self.advance::<T, LIT, MODE>(v, data, r, lv);
                        live = true;
                    }
                }
            }
            for (i, r) in &rays {
                if MODE != 0 {
                    // The projection: the extreme's colour and opacity over the background.
                    let (rgb, sigma) = match r.found {
                        true => self.transfer(r.m),
                        false => ([0.0; 3], 0.0),
                    };
                    let a = sigma.clamp(0.0, 1.0);
                    rows[*i] = Pixel {
                        rgba: [
                            rgb[0] * a + (1.0 - a) * bg[0],
                            rgb[1] * a + (1.0 - a) * bg[1],
                            rgb[2] * a + (1.0 - a) * bg[2],
                            a,
                        ],
                        volumetric: 1.0,
                        half: 0.0,
                    };
                    continue;
                }
                // A ray ended at OPAQUE: the rest of it as the mean of what it showed
                // (`occlusion::emission_absorption::end_opaque`), not the background.
                let (c, a) = if r.alpha > occlusion::emission_absorption::OPAQUE {
                    let (c, a) = occlusion::emission_absorption::end_opaque(
                        r.c.map(f64::from),
                        r.alpha as f64,
                    );
                    (c.map(|x| x as f32), a as f32)
                } else {
                    (r.c, r.alpha)
                };
                rows[*i] = Pixel {
                    rgba: [
                        c[0] + (1.0 - a) * bg[0],
                        c[1] + (1.0 - a) * bg[1],
                        c[2] + (1.0 - a) * bg[2],
                        a,
                    ],
                    // A weighted mean of light in [0, 1]: the tabled exponentials' rounding
                    // reached 1.000054.
                    volumetric: if r.acc[1] > 1e-6 {
                        (r.acc[0] / r.acc[1]).min(1.0)
                    } else {
                        1.0
                    },
                    half: r.half,
                };
            }
        }
    }

    /// Behind clipping planes, the ray's slabs: the planes keep one interval of its depths
    /// (`occlusion::emission_absorption::clip_interval` over all depths), so only the slabs
    /// where it begins and ends are cut (their parts found slab by slab, as before); the
    /// slabs wholly inside it (a slab of margin each way for rounding) are sampled as without
    /// planes (`Ray::inner`: the same sample, and empty blocks stepped over), and the ray's
    /// slices end a slab past the interval. Without this every slice of a clipped frame took
    /// the planes' intersections and a matrix product, and stepped over empty blocks a slice
    /// at a time (docs/benchmarks.md, "Clipped frames").
    #[inline(always)]
    fn clip_slabs(&self, v: &EaView, r: &mut Ray) {
        if r.k > r.k1 {
            return;
        }
        let (a, b) = occlusion::emission_absorption::clip_interval(
            v,
            r.o,
            r.d,
            f64::NEG_INFINITY,
            f64::INFINITY,
        );
        // NaN or nothing kept: every slab cut slab by slab (nothing behind the planes).
        if a.is_nan() || b.is_nan() || a >= b {
            return;
        }
        let (fa, fb) = (((a - v.z0) / v.dz).floor(), ((b - v.z0) / v.dz).floor());
        let last = r.k1 as f64;
        // The slabs holding the interval's ends, a slab of margin around them.
        if fa.is_finite() {
            r.k = r.k.max((fa - 1.0).clamp(0.0, last + 1.0) as u32);
        }
        if fb.is_finite() {
            r.k1 = r.k1.min((fb + 1.0).max(0.0).min(last) as u32);
            if fb + 1.0 < 0.0 {
                (r.k, r.k1) = (1, 0);
                return;
            }
        }
        let lo = if fa.is_finite() { fa + 2.0 } else { 0.0 };
        let hi = if fb.is_finite() { fb - 2.0 } else { last };
        if lo <= hi && hi >= 0.0 {
            r.inner = (lo.max(0.0).min(u32::MAX as f64) as u32, hi.min(last) as u32);
        }
    }

    /// A ray `o + s d` before its first sample: the slices in front of the eye where it is
    /// inside the grid (one slice of margin each way; every sample is checked again).
    /// Inlined into the march, which is compiled for AVX2 where the CPU has it: on its own
    /// its `floor` and `ceil` were calls into libm (measured with `pixel_ray`: 12% of a 512^2
    /// frame of the MNI T1 was setting rays up).
    #[inline(always)]
    fn start(&self, v: &EaView, o: DVec3, d: DVec3) -> Ray {
        self.start_along(v, v.camera.forward(), o, d)
    }

    /// [`EaVolume::start`] with the view's direction `f = v.camera.forward()` given.
    #[inline(always)]
    fn start_along(&self, v: &EaView, f: DVec3, o: DVec3, d: DVec3) -> Ray {
        let cosine = d.dot(f);
        let o_depth = (o - v.camera.eye).dot(f);
        let mut r = Ray {
            o,
            d,
            cosine,
            o_depth,
            qa: [0.0; 3],
            dq: [0.0; 3],
            seg: 0.0,
            k: 1,
            k1: 0,
            front: 0.0,
            c: [0.0; 3],
            alpha: 0.0,
            light: Footprint::default(),
            acc: [0.0; 2],
            half: 0.0,
            m: 0.0,
            found: false,
            inner: (1, 0),
            lstep: u32::MAX,
            lrun: 1.0,
            lgain: 1.0,
        };
        if cosine.is_nan() || cosine <= 1e-9 || v.slices == 0 {
            return r;
        }
        // Slice k's sample, at depth z0 + (k + 1/2) dz without clipping planes: index-space
        // q_k = qa + k dq.
        let w2i = self.world_to_index;
        let s0 = (v.z0 + 0.5 * v.dz - o_depth) / cosine;
        let qa = (w2i * DVec4::from((o + d * s0, 1.0))).truncate();
        let dq = DMat3::from_mat4(w2i) * (d * (v.dz / cosine));
        let hi = self.hi();
        r.front = ((o_depth - v.z0) / v.dz - 0.5) as f32;
        let front = ((o_depth - v.z0) / v.dz - 0.5).ceil().max(0.0);
        let (mut k0, mut k1) = (front, v.slices as f64 - 1.0);
        for a in 0..3 {
            if dq[a].abs() < 1e-12 {
                if qa[a] < 0.0 || qa[a] > hi[a] as f64 {
                    return r;
                }
                continue;
            }
            let (e0, e1) = (-qa[a] / dq[a], (hi[a] as f64 - qa[a]) / dq[a]);
            k0 = k0.max(e0.min(e1).floor() - 1.0);
            k1 = k1.min(e0.max(e1).ceil() + 1.0);
        }
        k0 = k0.max(front);
        if k1 < k0 {
            return r;
        }
        r.qa = qa.as_vec3().to_array();
        r.dq = dq.as_vec3().to_array();
        r.seg = (v.dz / cosine) as f32;
        (r.k, r.k1) = (k0 as u32, k1 as u32);
        r
    }

    /// The rays of four pixels of a row, `(xs[i], y)` (continuous positions), as
    /// [`pixel_ray`] and [`EaVolume::start_along`] give them, bit for bit: the same operations
    /// in the same order (glam's: a matrix times a vector column by column, a dot product
    /// left to right, no fused multiply-adds), each on four pixels at once in AVX lanes of
    /// f64, pushed to `out` with indices `at..at + 4`. A lane the scalar setup would leave
    /// early (a direction not into the slices, an axis the ray runs along, values that are not
    /// finite) is set up by the scalar code. (No closures: they would be compiled without
    /// AVX, each intrinsic a call.)
    ///
    /// # Safety
    /// The CPU has AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn rays4(
        &self,
        v: &EaView,
        inv: &DMat4,
        f: DVec3,
        xs: [f64; 4],
        y: f64,
        out: &mut Vec<(usize, Ray)>,
        at: usize,
    ) {
        use std::arch::x86_64::*;
        macro_rules! s {
            ($x:expr) => {
                _mm256_set1_pd($x)
            };
        }
        // Four lanes' `a op b` (a macro, not closures: see above).
        macro_rules! v {
            (add, $a:expr, $b:expr) => {
                _mm256_add_pd($a, $b)
            };
            (sub, $a:expr, $b:expr) => {
                _mm256_sub_pd($a, $b)
            };
            (mul, $a:expr, $b:expr) => {
                _mm256_mul_pd($a, $b)
            };
            (div, $a:expr, $b:expr) => {
                _mm256_div_pd($a, $b)
            };
        }
        // `m` (four columns) times `(x, y, z, w)` per lane, component `c`, as glam's
        // `DMat4 * DVec4`: ((X x + Y y) + Z z) + W w.
        macro_rules! mat4 {
            ($m:expr, $c:expr, $x:expr, $y:expr, $z:expr) => {
                v!(
                    add,
                    v!(
                        add,
                        v!(add, v!(mul, s!($m[0][$c]), $x), v!(mul, s!($m[1][$c]), $y)),
                        v!(mul, s!($m[2][$c]), $z)
                    ),
                    v!(mul, s!($m[3][$c]), s!(1.0))
                )
            };
        }
        // `u . w`, left to right.
        macro_rules! dot3 {
            ($u:expr, $w:expr) => {
                v!(
                    add,
                    v!(add, v!(mul, $u[0], s!($w[0])), v!(mul, $u[1], s!($w[1]))),
                    v!(mul, $u[2], s!($w[2]))
                )
            };
        }
        macro_rules! lanes {
            ($x:expr) => {{
                let mut o = [0f64; 4];
                // SAFETY: four f64 written to an array of four.
                unsafe { _mm256_storeu_pd(o.as_mut_ptr(), $x) };
                o
            }};
        }
        if v.slices == 0 {
            for (i, &x) in xs.iter().enumerate() {
                let (o, d) = pixel_ray(inv, v, [x, y]);
                out.push((at + i, self.start_along(v, f, o, d)));
            }
            return;
        }
        // pixel_ray.
        // SAFETY: four f64 read from an array of four.
        let px = unsafe { _mm256_loadu_pd(xs.as_ptr()) };
        let ndc_x = v!(
            sub,
            v!(div, v!(mul, s!(2.0), px), s!(v.width as f64)),
            s!(1.0)
        );
        let ndc_y = s!(1.0 - 2.0 * y / v.height as f64);
        let cols = [inv.x_axis, inv.y_axis, inv.z_axis, inv.w_axis];
        let p0 = [
            mat4!(cols, 0, ndc_x, ndc_y, s!(0.0)),
            mat4!(cols, 1, ndc_x, ndc_y, s!(0.0)),
            mat4!(cols, 2, ndc_x, ndc_y, s!(0.0)),
            mat4!(cols, 3, ndc_x, ndc_y, s!(0.0)),
        ];
        let p1 = [
            mat4!(cols, 0, ndc_x, ndc_y, s!(1.0)),
            mat4!(cols, 1, ndc_x, ndc_y, s!(1.0)),
            mat4!(cols, 2, ndc_x, ndc_y, s!(1.0)),
            mat4!(cols, 3, ndc_x, ndc_y, s!(1.0)),
        ];
        let a = [
            v!(div, p0[0], p0[3]),
            v!(div, p0[1], p0[3]),
            v!(div, p0[2], p0[3]),
        ];
        let b = [
            v!(div, p1[0], p1[3]),
            v!(div, p1[1], p1[3]),
            v!(div, p1[2], p1[3]),
        ];
        let dd = [
            v!(sub, b[0], a[0]),
            v!(sub, b[1], a[1]),
            v!(sub, b[2], a[2]),
        ];
        let len2 = v!(
            add,
            v!(add, v!(mul, dd[0], dd[0]), v!(mul, dd[1], dd[1])),
            v!(mul, dd[2], dd[2])
        );
        let recip = v!(div, s!(1.0), _mm256_sqrt_pd(len2));
        let d = [
            v!(mul, dd[0], recip),
            v!(mul, dd[1], recip),
            v!(mul, dd[2], recip),
        ];
        // start_along.
        let fa = f.to_array();
        let cosine = dot3!(d, fa);
        let eye = v.camera.eye;
        let oe = [
            v!(sub, a[0], s!(eye.x)),
            v!(sub, a[1], s!(eye.y)),
            v!(sub, a[2], s!(eye.z)),
        ];
        let o_depth = dot3!(oe, fa);
        let s0 = v!(div, v!(sub, s!(v.z0 + 0.5 * v.dz), o_depth), cosine);
        let w2i = self.world_to_index;
        let m = [w2i.x_axis, w2i.y_axis, w2i.z_axis, w2i.w_axis];
        let p = [
            v!(add, a[0], v!(mul, d[0], s0)),
            v!(add, a[1], v!(mul, d[1], s0)),
            v!(add, a[2], v!(mul, d[2], s0)),
        ];
        let qa = [
            mat4!(m, 0, p[0], p[1], p[2]),
            mat4!(m, 1, p[0], p[1], p[2]),
            mat4!(m, 2, p[0], p[1], p[2]),
        ];
        let t = v!(div, s!(v.dz), cosine);
        let e = [v!(mul, d[0], t), v!(mul, d[1], t), v!(mul, d[2], t)];
        // `DMat3::from_mat4(m) * e`: ((X x + Y y) + Z z).
        let dq = [
            v!(
                add,
                v!(add, v!(mul, s!(m[0][0]), e[0]), v!(mul, s!(m[1][0]), e[1])),
                v!(mul, s!(m[2][0]), e[2])
            ),
            v!(
                add,
                v!(add, v!(mul, s!(m[0][1]), e[0]), v!(mul, s!(m[1][1]), e[1])),
                v!(mul, s!(m[2][1]), e[2])
            ),
            v!(
                add,
                v!(add, v!(mul, s!(m[0][2]), e[0]), v!(mul, s!(m[1][2]), e[1])),
                v!(mul, s!(m[2][2]), e[2])
            ),
        ];
        let front_f = v!(sub, v!(div, v!(sub, o_depth, s!(v.z0)), s!(v.dz)), s!(0.5));
        let front = _mm256_max_pd(_mm256_round_pd::<_MM_FROUND_TO_POS_INF>(front_f), s!(0.0));
        let hi = self.hi();
        let (mut k0, mut k1) = (front, s!(v.slices as f64 - 1.0));
        let sign = s!(-0.0);
        let inf = s!(f64::INFINITY);
        // Lanes the scalar code takes: not into the slices (or NaN), along an axis, not finite.
        let mut odd = _mm256_cmp_pd::<_CMP_NGT_UQ>(cosine, s!(1e-9));
        odd = _mm256_or_pd(
            odd,
            _mm256_cmp_pd::<_CMP_NLT_UQ>(_mm256_andnot_pd(sign, front_f), inf),
        );
        for c in 0..3 {
            let (qc, dc) = (qa[c], dq[c]);
            odd = _mm256_or_pd(
                odd,
                _mm256_cmp_pd::<_CMP_LT_OQ>(_mm256_andnot_pd(sign, dc), s!(1e-12)),
            );
            let e0 = v!(div, _mm256_xor_pd(qc, sign), dc);
            let e1 = v!(div, v!(sub, s!(hi[c] as f64), qc), dc);
            odd = _mm256_or_pd(
                odd,
                _mm256_cmp_pd::<_CMP_NLT_UQ>(_mm256_andnot_pd(sign, e0), inf),
            );
            odd = _mm256_or_pd(
                odd,
                _mm256_cmp_pd::<_CMP_NLT_UQ>(_mm256_andnot_pd(sign, e1), inf),
            );
            let lo = _mm256_round_pd::<_MM_FROUND_TO_NEG_INF>(_mm256_min_pd(e0, e1));
            let up = _mm256_round_pd::<_MM_FROUND_TO_POS_INF>(_mm256_max_pd(e0, e1));
            k0 = _mm256_max_pd(k0, v!(sub, lo, s!(1.0)));
            k1 = _mm256_min_pd(k1, v!(add, up, s!(1.0)));
        }
        k0 = _mm256_max_pd(k0, front);
        let odd = _mm256_movemask_pd(odd);
        let (ax, ay, az) = (lanes!(a[0]), lanes!(a[1]), lanes!(a[2]));
        let (dx, dy, dz) = (lanes!(d[0]), lanes!(d[1]), lanes!(d[2]));
        let (cosine, o_depth, front_f) = (lanes!(cosine), lanes!(o_depth), lanes!(front_f));
        let (qx, qy, qz) = (lanes!(qa[0]), lanes!(qa[1]), lanes!(qa[2]));
        let (ex, ey, ez) = (lanes!(dq[0]), lanes!(dq[1]), lanes!(dq[2]));
        let (k0, k1) = (lanes!(k0), lanes!(k1));
        for i in 0..4 {
            if odd & (1 << i) != 0 {
                let (o, d) = pixel_ray(inv, v, [xs[i], y]);
                out.push((at + i, self.start_along(v, f, o, d)));
                continue;
            }
            let mut r = Ray {
                o: DVec3::new(ax[i], ay[i], az[i]),
                d: DVec3::new(dx[i], dy[i], dz[i]),
                cosine: cosine[i],
                o_depth: o_depth[i],
                qa: [0.0; 3],
                dq: [0.0; 3],
                seg: 0.0,
                k: 1,
                k1: 0,
                front: front_f[i] as f32,
                c: [0.0; 3],
                alpha: 0.0,
                light: Footprint::default(),
                acc: [0.0; 2],
                half: 0.0,
                m: 0.0,
                found: false,
                inner: (1, 0),
                lstep: u32::MAX,
                lrun: 1.0,
                lgain: 1.0,
            };
            if k1[i] >= k0[i] {
                r.qa = [qx[i] as f32, qy[i] as f32, qz[i] as f32];
                r.dq = [ex[i] as f32, ey[i] as f32, ez[i] as f32];
                r.seg = (v.dz / cosine[i]) as f32;
                (r.k, r.k1) = (k0[i] as u32, k1[i] as u32);
            }
            out.push((at + i, r));
        }
    }

    /// Whether `lanes` can march this volume's `data` in view `v` (with the light volume `lv`
    /// for a lit frame): samples bricked or in the grid's layout (at least four, fewer than
    /// 2^31: the gathers' indices), a transfer function with points, no clipping planes (with
    /// planes: [`EaVolume::lanes_apply_planes`]), at most `MAX_SLICES` slices, a light volume of
    /// fewer than 2^31 values, and `self.lanes` on.
    #[cfg(target_arch = "x86_64")]
    fn lanes_apply<T: Voxel>(&self, v: &EaView, data: &[T], lv: Option<&LightVolume>) -> bool {
        v.clip.is_empty() && self.lanes_apply_planes(v, data, lv)
    }

    /// [`EaVolume::lanes_apply`] but for the clipping planes: the eye's march of a clipped
    /// unlit frame (`ea` or a projection) samples the slabs wholly behind the planes
    /// (`Ray::inner`) as without them, eight rays at a time ([`EaVolume::march_clipped`]).
    #[cfg(target_arch = "x86_64")]
    fn lanes_apply_planes<T: Voxel>(
        &self,
        v: &EaView,
        data: &[T],
        lv: Option<&LightVolume>,
    ) -> bool {
        self.lanes
            && !self.tf.is_empty()
            && v.slices <= occlusion::emission_absorption::MAX_SLICES
            && (4..i32::MAX as usize).contains(&data.len())
            && lv.is_none_or(|l| l.values().len() < i32::MAX as usize)
    }

    /// Marches `rays` eight at a time (`lanes`) over `data` retyped to its stored type;
    /// `false` (nothing done) for a type `lanes` does not gather.
    ///
    /// # Safety
    /// The CPU has AVX2 and FMA, and [`EaVolume::lanes_apply`] holds for `v`, `data` (the
    /// volume's samples) and `lv` (the light volume swept for `v`, for a lit frame); `splat`
    /// is this volume's; `rays` come from [`EaVolume::start`] for `v`.
    #[cfg(target_arch = "x86_64")]
    unsafe fn march_lanes<T: Voxel, const LIT: bool>(
        &self,
        splat: &lanes::Splat<'_>,
        v: &EaView,
        data: &[T],
        lv: &LightVolume,
        rays: &mut [(usize, Ray)],
    ) -> bool {
        lanes::by_stored_type!(T, data, d: G => {
            for l in rays.chunks_mut(lanes::LANES) {
                // SAFETY: the caller's.
                unsafe { lanes::march::<G, LIT>(splat, d, v, lv, l) };
            }
            true
        }, else false)
    }

    /// The rays of a clipped unlit frame (`MODE` 0: `ea`; 1, 2: a projection) marched to
    /// their ends: the slabs before their `Ray::inner` (cut by the planes) by the scalar
    /// march, the slabs of `inner` - sampled as without planes - eight rays at a time (the
    /// same samples and operations, so the same pixels bit for bit), the cut slabs after it by
    /// the scalar march again. Rays whose `inner` is empty are marched by the scalar march
    /// alone. `false`
    /// (nothing done) for a type `lanes` does not gather.
    ///
    /// # Safety
    /// As [`EaVolume::march_lanes`]'s, with [`EaVolume::lanes_apply_planes`] for `v` (and
    /// `lv`, lit).
    #[cfg(target_arch = "x86_64")]
    unsafe fn march_clipped<T: Voxel, const LIT: bool, const MODE: u8>(
        &self,
        splat: &lanes::Splat<'_>,
        v: &EaView,
        data: &[T],
        lv: &LightVolume,
        rays: &mut [(usize, Ray)],
    ) -> bool {
        if !lanes::gathers::<T>() {
            return false;
        }
        let has_inner = |r: &Ray| r.inner.0 <= r.inner.1;
        // The cut slabs in front of `inner` (all of a ray's slabs without one).
        for (_, r) in rays.iter_mut() {
            while r.next().is_some() && !(has_inner(r) && r.k >= r.inner.0) {
                self.advance::<T, LIT, MODE>(v, data, r, lv);
            }
        }
        // `inner`: the rays still marching end there for the lanes (`last`: their own last
        // slice). A lane that ends early (opaque, or a projection's transparent end) leaves
        // k1 = 0, k = 1; one that does not, k1 as given.
        // (Rays already past `inner` sit the lanes out as done rays, k = 1 > k1 = 0. So do
        // rays whose `inner` is slice 0 alone: a lane that ends there early leaves k1 = 0 =
        // inner.1, as one that does not - the scalar march takes slice 0 as the lanes would.)
        let mut last = [None; TILE * TILE];
        for ((_, r), l) in rays.iter_mut().zip(&mut last) {
            if r.next().is_some() {
                let lanes = r.k <= r.inner.1 && r.inner.1 > 0;
                *l = Some((r.k, r.k1, lanes));
                (r.k, r.k1) = if lanes {
                    (r.k, r.k1.min(r.inner.1))
                } else {
                    (1, 0)
                };
            }
        }
        // SAFETY: the caller's; the rays' slices k..=k1 lie in `inner`, where the planes
        // change no sample (`EaVolume::advance`).
        unsafe {
            if MODE == 0 {
                self.march_lanes::<T, LIT>(splat, v, data, lv, rays);
            } else {
                self.march_lanes_extreme::<T, MODE>(splat, data, rays);
            }
        }
        // Past `inner`, the scalar march; a lane's step over empty blocks not past `inner`'s
        // end, as `advance` takes it. (inner.1 > 0: a lane that ended early has k1 = 0 <
        // min(last, inner.1) unless `last` is 0, where both cases leave the ray done.)
        for ((_, r), l) in rays.iter_mut().zip(last) {
            let Some((k, l, lanes)) = l else { continue };
            if !lanes {
                (r.k, r.k1) = (k, l);
            } else if r.k1 == l.min(r.inner.1) {
                r.k1 = l;
                r.k = r.k.min(r.inner.1.saturating_add(1));
            }
            while r.next().is_some() {
                self.advance::<T, LIT, MODE>(v, data, r, lv);
            }
        }
        true
    }

    /// [`EaVolume::march_lanes`] for a projection (`MODE` 1 or 2): `lanes::march_extreme`.
    ///
    /// # Safety
    /// As [`EaVolume::march_lanes`]'s.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn march_lanes_extreme<T: Voxel, const MODE: u8>(
        &self,
        splat: &lanes::Splat<'_>,
        data: &[T],
        rays: &mut [(usize, Ray)],
    ) -> bool {
        // As the scalar march: the transparent side of empty blocks is the extreme's.
        let ends = (MODE == 1) != self.clear_below;
        lanes::by_stored_type!(T, data, d: G => {
            for l in rays.chunks_mut(lanes::LANES) {
                // SAFETY: the caller's.
                unsafe { lanes::march_extreme::<G, MODE>(splat, d, l, ends) };
            }
            true
        }, else false)
    }

    /// The grid's last index per axis.
    #[inline(always)]
    fn hi(&self) -> [f32; 3] {
        self.hi
    }

    /// Takes the ray's next slice: skips it (outside the grid or clipped away), steps over
    /// the empty brick it falls in, or composites its sample; ends the ray when opaque.
    #[inline(always)]
    fn advance<T: Voxel, const LIT: bool, const MODE: u8>(
        &self,
        v: &EaView,
        data: &[T],
        r: &mut Ray,
        lv: &LightVolume,
    ) {
        let k = r.k;
        let kf = k as f32;
        let mut q = [0, 1, 2].map(|a| r.qa[a] + kf * r.dq[a]);
        let mut len = r.seg;
        let mut depth = v.z0 + (k as f64 + 0.5) * v.dz;
        let planes = !v.clip.is_empty();
        // Slabs wholly behind the planes are sampled as without them (`EaVolume::clip_slabs`).
        let clipped = planes && !r.inner_has(k);
        if clipped {
            // The slab's part behind the clipping planes, sampled at its middle.
            let (lo, hi) = slab_interval(v, r.o, r.d, k);
            let s = (0.5 * (lo + hi) - r.o_depth) / r.cosine;
            if hi <= lo || s < 0.0 {
                r.k += 1;
                return;
            }
            let p = self.world_to_index * DVec4::from((r.o + r.d * s, 1.0));
            q = p.truncate().as_vec3().to_array();
            len = ((hi - lo) / r.cosine) as f32;
            depth = 0.5 * (lo + hi);
        }
        let hi = self.hi();
        if (0..3).any(|a| !(q[a] >= 0.0 && q[a] <= hi[a])) {
            r.k += 1;
            return;
        }
        let (cell, block, b) = self.cell(q);
        // A projection's extreme lies towards the transparent side of empty blocks: a sample
        // there makes the ray transparent (unless it is a gap).
        let ends = MODE != 0 && (MODE == 1) != self.clear_below;
        if !self.occupied[block] && ends {
            r.k += 1;
            let f = [0, 1, 2].map(|a| q[a] - cell[a] as f32);
            if EaVolume::trilinear(&self.corners(data, cell), f) >= -1e30 {
                r.found = false;
                r.k1 = 0;
                r.k = 1;
            }
            return;
        }
        if !self.occupied[block] {
            // Step to the first slice past the empty cube of blocks around this one: the
            // samples before it are in empty blocks, transparent.
            let d = self.reach[block] as usize;
            r.k = k.saturating_add(if clipped { 1 } else { r.past_block(q, b, d) });
            if planes {
                // Not past the cut slabs at the back: their parts' samples are not the
                // slices'.
                r.k = r.k.min(r.inner.1.saturating_add(1).max(k + 1));
            }
            return;
        }
        r.k += 1;
        // (Keeping the corners of the last cell in the ray, to read them once for the two to
        // four samples a cell takes, measured 1.3x slower on headsq: the copies cost more
        // than the loads from L1.)
        // (`as u32 as f32`: one conversion; `usize as f32` branches on the sign bit.)
        let f = [0, 1, 2].map(|a| q[a] - cell[a] as u32 as f32);
        let val = EaVolume::trilinear(&self.corners(data, cell), f) + self.offset;
        if val < -1e30 {
            return;
        }
        if MODE != 0 {
            if !r.found || (MODE == 1 && val > r.m) || (MODE == 2 && val < r.m) {
                r.m = val;
                r.found = true;
            }
            return;
        }
        let (rgb, sigma) = self.transfer(val);
        if sigma <= 0.0 {
            return;
        }
        let e = self.exp_neg(sigma * len);
        let wgt = (1.0 - r.alpha) * (1.0 - e);
        if LIT {
            // The light along the ray's own path through its light step
            // (`occlusion::combined::light_in_slab`): the step's front from the light volume,
            // then attenuated by the ray's samples; this sample's light weighted by the eye's
            // attenuation within its slab.
            let s = k >> lv.eye_step_shift;
            if s != r.lstep {
                let first = r.lstep == u32::MAX;
                let front = lv.front(&r.light, k, first);
                (r.lrun, r.lgain) = if first || !r.light.shifted {
                    (front, 1.0)
                } else {
                    light::front_gain(r.lrun, front, lv.eye_step_shift)
                };
                r.lstep = s;
            }
            let ef = self.exp_neg(lv.path * (sigma * len));
            let lw = (1.0 - r.alpha) * (r.lrun * ((1.0 - e * ef) * lv.inv_1f));
            r.lrun *= ef * r.lgain;
            for (c, x) in r.c.iter_mut().zip(rgb) {
                *c += lw * x;
            }
            r.acc[0] += lw;
        } else {
            for (c, x) in r.c.iter_mut().zip(rgb) {
                *c += wgt * x;
            }
            r.acc[0] += wgt;
        }
        let before = r.alpha;
        r.alpha += wgt;
        r.acc[1] += wgt;
        if r.alpha >= 0.5 && before < 0.5 {
            r.half = depth as f32;
        }
        if r.alpha > occlusion::emission_absorption::OPAQUE {
            r.k1 = 0;
            r.k = 1;
        }
    }
}

impl EaVolume {
    /// The optical depths `sigma len / cos` of the `n` equal parts of slab `k` along ray `r`
    /// (each clipped by the clipping planes only, and sampled at its middle;
    /// `occlusion::combined::light_samples`; 1: the whole slab at its middle): 0 outside the grid, in
    /// an empty block, next to a gap or where the transfer function is transparent. The light
    /// leaving a cell through a slice is `exp(-f` this `)`, `f` the light's path factor
    /// (`occlusion::combined::cone_path_factor`, applied by `light::Sweep`). Also the next slice whose optical
    /// depth may not be 0 (past an empty block where every sample is in one, the ray's first
    /// slice in the grid; `u32::MAX` past its last).
    #[inline(always)]
    pub(crate) fn optical_depth<T: Voxel>(
        &self,
        v: &EaView,
        data: &[T],
        r: &Ray,
        k: u32,
        n: u32,
    ) -> (Parts, u32) {
        let mut tau: Parts = [0.0; MAX_PARTS];
        if k < r.k {
            return (tau, r.k);
        }
        if k > r.k1 {
            return (tau, u32::MAX);
        }
        let n = n.clamp(1, MAX_PARTS as u32);
        let planes = !v.clip.is_empty();
        // Slabs wholly behind the planes are sampled as without them (`EaVolume::clip_slabs`).
        let clipped = planes && !r.inner_has(k);
        let hi = self.hi();
        let mut skip = u32::MAX;
        for i in 0..n {
            let (q, len) = if clipped {
                // Each part of the slab clipped on its own, as the steps a part deep would be.
                let a = v.z0 + (k as f64 + i as f64 / n as f64) * v.dz;
                let (lo, hi) = clip_interval(v, r.o, r.d, a, a + v.dz / n as f64);
                let s = (0.5 * (lo + hi) - r.o_depth) / r.cosine;
                if hi <= lo || s < 0.0 {
                    skip = 1;
                    continue;
                }
                let p = self.world_to_index * DVec4::from((r.o + r.d * s, 1.0));
                (
                    p.truncate().as_vec3().to_array(),
                    ((hi - lo) / r.cosine) as f32,
                )
            } else {
                let kf = k as f32 + sub_offset(i, n);
                if kf < r.front {
                    // Behind the ray's origin (a camera inside the grid).
                    skip = 1;
                    continue;
                }
                ([0, 1, 2].map(|a| r.qa[a] + kf * r.dq[a]), r.seg / n as f32)
            };
            if (0..3).any(|a| !(q[a] >= 0.0 && q[a] <= hi[a])) {
                skip = 1;
                continue;
            }
            let (cell, block, b) = self.cell(q);
            if !self.occupied[block] {
                let d = self.reach[block] as usize;
                skip = skip.min(if clipped { 1 } else { r.past_block(q, b, d) });
                continue;
            }
            skip = 1;
            let f = [0, 1, 2].map(|a| q[a] - cell[a] as f32);
            let val = EaVolume::trilinear(&self.corners(data, cell), f) + self.offset;
            if val < -1e30 {
                continue;
            }
            tau[i as usize] = self.transfer(val).1.max(0.0) * len;
        }
        (tau, k.saturating_add(skip))
    }
}

/// The most parts a light step's slab is sampled in (`occlusion::combined::light_samples`).
pub(crate) const MAX_PARTS: usize = occlusion::combined::MAX_LIGHT_STEP as usize;

/// The optical depths of a step's parts, in order (0 past the step's count).
pub(crate) type Parts = [f32; MAX_PARTS];

/// Where sample `i` of `n` lies in its slab, in slices from the slab's middle: the middle of
/// the `i`-th of `n` equal parts (0 for one sample).
#[inline(always)]
pub(crate) fn sub_offset(i: u32, n: u32) -> f32 {
    (i as f32 + 0.5) / n as f32 - 0.5
}

/// Entries of the exponential's table per unit of `x`, and its entries: `exp(-x)` is tabled on
/// `[0, 16]` (beyond, below 1.2e-7, it is taken as 0).
const EXP_SCALE: f32 = 128.0;
const EXP_N: usize = 16 * 128;

impl EaVolume {
    /// `exp(-x)` for `x >= 0` from a table, linearly interpolated: within `h^2 / 8 = 8e-6`
    /// (`h = 1 / EXP_SCALE`) absolute, a few instructions instead of the polynomial's score.
    #[inline(always)]
    fn exp_neg(&self, x: f32) -> f32 {
        let t = x * EXP_SCALE;
        if t.is_nan() || t <= 0.0 {
            return 1.0;
        }
        if t >= EXP_N as f32 {
            return 0.0;
        }
        // (Through u32, one conversion each way: see `cell`.)
        let i = t as u32;
        let f = t - i as f32;
        let i = i as usize;
        let (a, b) = (self.exp_table[i], self.exp_table[i + 1]);
        a + (b - a) * f
    }
}

/// Edge of the empty-space blocks the rays step over, in cells: finer than the GPU pass's
/// bricks (`BRICK`), since a CPU ray pays for every sample (measured: a quarter to two fifths
/// of the samples in 8^3 bricks were transparent on the MNI T1 and headsq).
const SKIP: usize = 4;

/// The largest skip distance kept, in blocks.
const REACH: u8 = 16;

/// [`EaVolume::reach`] from the blocks' occupancy (`nb` per axis, x fastest): the cube of
/// radius `r` around a block grows by one block per axis a round (a separable dilation),
/// and a block first reached in round `r` is `r` from the nearest occupied block; blocks
/// not reached in [`REACH`] rounds keep [`REACH`].
fn reach_of(occ: &[u32], nb: [usize; 3]) -> Vec<u8> {
    let mut reach: Vec<u8> = occ
        .iter()
        .map(|&o| if o != 0 { 0 } else { REACH })
        .collect();
    let mut hit: Vec<bool> = occ.iter().map(|&o| o != 0).collect();
    let idx = |x: usize, y: usize, z: usize| x + nb[0] * (y + nb[1] * z);
    for r in 1..REACH {
        // Dilate `hit` by one block along x, then y, then z: the 3^3 cube.
        for axis in 0..3 {
            let prev = hit.clone();
            for z in 0..nb[2] {
                for y in 0..nb[1] {
                    for x in 0..nb[0] {
                        let p = [x, y, z];
                        let mut any = prev[idx(x, y, z)];
                        for step in [-1i64, 1] {
                            let c = p[axis] as i64 + step;
                            if !any && c >= 0 && (c as usize) < nb[axis] {
                                let mut n = p;
                                n[axis] = c as usize;
                                any = prev[idx(n[0], n[1], n[2])];
                            }
                        }
                        hit[idx(x, y, z)] = any;
                    }
                }
            }
        }
        let mut grew = false;
        for (h, d) in hit.iter().zip(reach.iter_mut()) {
            if *h && *d == REACH {
                *d = r;
                grew = true;
            }
        }
        if !grew {
            break;
        }
    }
    reach
}

/// Bytes of `f32` samples beyond which integer data is kept in `u8` or `u16`.
pub const NARROW_ABOVE: usize = 256 << 20;

/// The largest copy of a shared volume's samples in bricks [`EaVolume::shared`] makes (the
/// MNI T1 template's is 12 MB in `u8`, 50 MB in `f32`; a 256^3 volume's in `f32` would be 95
/// MB).
pub const COPY_AT_MOST: usize = 64 << 20;

/// Samples per brick edge in memory: a brick of `BRICK^3` cells with its far faces, so that
/// every cell's eight corners are in one brick.
const APRON: usize = BRICK + 1;

/// `data` (x fastest) in bricks: the bricks of `occupancy` (cells `[b B, (b + 1) B]` per
/// axis) one after the other, x fastest, each `APRON^3` samples, x fastest within (faces
/// shared by two bricks are stored twice; samples beyond the grid repeat its last). A
/// trilinear sample then reads two cache lines for the bytes of a brick's slice instead of
/// four rows of the whole grid, and a ray's next samples mostly fall in the same brick.
fn bricked<T: Voxel>(
    data: &[f32],
    dims: [usize; 3],
    bricks: [usize; 3],
    to: impl Fn(f32) -> T + Sync,
) -> Vec<T> {
    let mut out = vec![to(0.0); APRON.pow(3) * bricks.iter().product::<usize>()];
    bricked_into(data, dims, bricks, &mut out, to);
    out
}

/// The samples `data` (as [`EaVolume::shared`] holds them) copied to bricks in `packing`,
/// straight from their stored type where it is the packing's (no `f32` copy on the way: a
/// narrow copy's peak is its own size), else through their values.
fn bricks_of(data: &Samples, dims: [usize; 3], bricks: [usize; 3], packing: Packing) -> Samples {
    let n = APRON.pow(3) * bricks.iter().product::<usize>();
    let o = packing.offset();
    match (data.view(), packing) {
        (View::F32(d), Packing::F32) => Samples::f32(bricked(d, dims, bricks, |v| v)),
        (View::U8(d, _), Packing::U8 { .. }) if data.packing() == packing => {
            Samples::from_fill(n, packing, |b: &mut [u8]| {
                bricked_into(d, dims, bricks, b, |v| v)
            })
        }
        (View::U16(d, _), Packing::U16 { .. }) if data.packing() == packing => {
            Samples::from_fill(n, packing, |h: &mut [u16]| {
                bricked_into(d, dims, bricks, h, |v| v)
            })
        }
        (View::F32(d), Packing::U8 { .. }) => Samples::from_fill(n, packing, |b: &mut [u8]| {
            bricked_into(d, dims, bricks, b, |v| (v - o) as u8)
        }),
        (View::F32(d), Packing::U16 { .. }) => Samples::from_fill(n, packing, |h: &mut [u16]| {
            bricked_into(d, dims, bricks, h, |v| (v - o) as u16)
        }),
        _ => Samples::pack_as(bricked(&data.to_f32(), dims, bricks, |v| v), packing),
    }
}

/// [`bricked`] into `out` (`APRON^3` samples a brick), from samples of any stored type.
fn bricked_into<S: Copy + Sync, T: Copy + Send>(
    data: &[S],
    dims: [usize; 3],
    bricks: [usize; 3],
    out: &mut [T],
    to: impl Fn(S) -> T + Sync,
) {
    let n = APRON.pow(3);
    debug_assert_eq!(out.len(), n * bricks.iter().product::<usize>());
    out.par_chunks_mut(n).enumerate().for_each(|(b, brick)| {
        let (bx, by, bz) = (
            b % bricks[0],
            (b / bricks[0]) % bricks[1],
            b / (bricks[0] * bricks[1]),
        );
        let mut s = brick.iter_mut();
        for lz in 0..APRON {
            let z = (bz * BRICK + lz).min(dims[2] - 1);
            for ly in 0..APRON {
                let y = (by * BRICK + ly).min(dims[1] - 1);
                let row = &data[dims[0] * (y + dims[1] * z)..][..dims[0]];
                for lx in 0..APRON {
                    let x = (bx * BRICK + lx).min(dims[0] - 1);
                    *s.next().expect("APRON^3 samples a brick") = to(row[x]);
                }
            }
        }
    });
}

/// `f32` samples in `u8` or `u16` (offset 0) where every one is an integer from 0 to 255 or
/// 65,535, for the light sweep; `None` otherwise or when they are narrow already.
fn narrowed(data: &Samples) -> Option<Samples> {
    let View::F32(d) = data.view() else {
        return None;
    };
    let fits = |max: f32| {
        d.par_iter()
            .all(|&v| v >= 0.0 && v <= max && v == v.trunc())
    };
    let packing = match () {
        _ if fits(255.0) => Packing::U8 { offset: 0.0 },
        _ if fits(65535.0) => Packing::U16 { offset: 0.0 },
        _ => return None,
    };
    Some(Samples::pack_as(d.to_vec(), packing))
}

/// A band of rows to render: the view, the samples, the inverse view-projection, the
/// background, the band's index and its rows of the image.
struct Band<'a, T> {
    v: &'a EaView,
    data: &'a [T],
    inv: glam::DMat4,
    bg: [f32; 3],
    band: usize,
    rows: &'a mut [Pixel],
    light: Option<&'a LightVolume>,
    /// Behind clipping planes, lit: the light cells' entries ([`LightVolume::clip_entries`]).
    entries: &'a [Option<f64>],
    /// 0: emission-absorption; 1, 2: the maximum or minimum projection.
    mode: u8,
    /// The CPU has AVX2 and FMA (`lanes` may march the packets).
    simd: bool,
}

/// What a ray leaves in its pixel.
#[derive(Clone, Copy, Default)]
struct Pixel {
    rgba: [f32; 4],
    volumetric: f32,
    half: f32,
}

/// Pixels per side of a packet of rays marched together.
const TILE: usize = 4;

/// A ray's march: its samples `q_k = qa + k dq` (index space), its next slice `k` and last
/// `k1` (none left when `k > k1`), and what it has gathered (premultiplied colour, opacity).
struct Ray {
    o: DVec3,
    d: DVec3,
    cosine: f64,
    o_depth: f64,
    qa: [f32; 3],
    dq: [f32; 3],
    seg: f32,
    k: u32,
    k1: u32,
    /// The fractional slice whose sample lies at the ray's origin: samples before it are
    /// behind the eye (the first slice `k` is the first at or after it).
    front: f32,
    c: [f32; 3],
    alpha: f32,
    /// Where the ray reads the light volume (lit frames).
    light: Footprint,
    /// The opacity-weighted sum of `O` and the sum of the weights (the volumetric AOV).
    acc: [f32; 2],
    /// The view depth where the opacity passed 0.5 (0: not yet).
    half: f32,
    /// Projections: the extreme sample so far, and whether there is one.
    m: f32,
    found: bool,
    /// Behind clipping planes: the slabs wholly inside the depths the planes keep of the ray
    /// (`inner.0..=inner.1`, none by default), sampled as without planes; the others' parts
    /// behind the planes are found slab by slab ([`EaVolume::clip_slabs`]).
    inner: (u32, u32),
    /// Lit: the light step the ray last read the light volume at (`u32::MAX`: none yet) and
    /// the light reaching its next sample along the ray (`LightVolume::front`, attenuated by
    /// the samples since; `occlusion::combined::light_in_slab`), and behind clipping planes
    /// the factor each sample brings it towards the last front read (`light::front_gain`).
    lstep: u32,
    lrun: f32,
    lgain: f32,
}

impl Ray {
    /// Slices from the one at `q` (in the empty skip block `b`, whose empty cube of blocks
    /// reaches `d >= 1` blocks: blocks `b - (d - 1) ..= b + (d - 1)` per axis, cells
    /// `[(b - d + 1) S, (b + d) S]`) to the first past the cube, at least 1: the samples
    /// before it are in empty blocks, transparent (truncation floors the non-negative step
    /// count).
    #[inline(always)]
    fn past_block(&self, q: [f32; 3], b: [usize; 3], d: usize) -> u32 {
        let mut steps = u32::MAX;
        for a in 0..3 {
            let dqa = self.dq[a];
            if dqa.abs() < 1e-12 {
                continue;
            }
            let edge = if dqa > 0.0 {
                ((b[a] + d) * SKIP) as f32
            } else {
                ((b[a] + 1).saturating_sub(d) * SKIP) as f32
            };
            let n = ((edge - q[a]) / dqa).max(0.0) as u32;
            steps = steps.min(n.saturating_add(1));
        }
        steps.max(1)
    }

    /// Whether slice `k` lies in [`Ray::inner`] (behind the planes, sampled as without them).
    #[inline(always)]
    fn inner_has(&self, k: u32) -> bool {
        self.inner.0 <= k && k <= self.inner.1
    }

    /// The next slice to take, if any.
    #[inline(always)]
    fn next(&self) -> Option<u32> {
        (self.k <= self.k1).then_some(self.k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use occlusion::camera::Camera;
    use occlusion::emission_absorption::reference;
    use volume::{Field, ScalarType, Space, Volume};

    /// A Gaussian blob with a NaN hole and an empty margin (bricks to skip), on an
    /// anisotropic grid off the origin.
    fn blob(dims: [usize; 3]) -> Volume {
        let mut v = volume::synthetic::gaussian_blob(dims, DVec3::new(-20.0, -18.0, -16.0), 40.0);
        if dims.iter().all(|&n| n > 20) {
            let i = v.index(20, 20, 14);
            v.fields[0].data[i] = f32::NAN;
        }
        v
    }

    /// A camera at the centre of the grid `b` (its near plane past the first slices), looking
    /// off the axes.
    fn inside_camera(b: [DVec3; 2]) -> Camera {
        let c = 0.5 * (b[0] + b[1]);
        Camera {
            eye: c,
            target: c + DVec3::new(0.6, -0.3, 0.5),
            near: 2.6,
            ..Camera::orbit(b, 40.0, 25.0, 2.5, Some(60.0))
        }
    }

    /// A projection's window as a transfer function: nine points from `lo` to `hi` (colour
    /// and extinction), transparent just past `lo` (below it, or above a window turned round).
    fn window_ramp(lo: f64, hi: f64) -> Transfer {
        let mut points: Vec<(f64, [f64; 3], f64)> = (0..=8)
            .map(|k| {
                let t = k as f64 / 8.0;
                (lo + (hi - lo) * t, [t, 0.5 * t, 1.0 - t], 0.9)
            })
            .collect();
        points.push((lo - 1e-6 * (hi - lo), [0.0; 3], 0.0));
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        Transfer {
            points,
            rows: vec![],
        }
    }

    fn tf() -> Transfer {
        Transfer {
            points: vec![
                (0.1, [0.0, 0.0, 0.0], 0.0),
                (0.5, [0.2, 0.4, 1.0], 0.3),
                (0.9, [1.0, 0.6, 0.2], 0.9),
            ],
            rows: vec![],
        }
    }

    #[test]
    fn the_cpu_renderer_matches_the_f64_twin() {
        let vol = blob([40, 44, 30]);
        let data = vol.select(None).unwrap().data;
        let ev = EaVolume::new(&vol, &data, &tf()).unwrap();
        assert_eq!(ev.storage(), "f32");
        assert!(
            ev.occupied.iter().any(|o| !o) && ev.occupied.iter().any(|o| *o),
            "the test needs empty and occupied bricks"
        );
        let b = vol.bounds();
        let persp = Camera::orbit(b, 40.0, 25.0, 2.5, Some(40.0));
        let inside = Camera::orbit(b, 10.0, -30.0, 1.01, Some(70.0));
        for (cam, clip) in [
            (persp, vec![]),
            (Camera::orbit(b, -70.0, 60.0, 3.0, None), vec![]),
            (persp, vec![([1.0, 0.0, 0.0], 1.5)]),
            (inside, vec![]),
        ] {
            let mut view = EaView::new(&vol, cam, 48, 40, None, None, [0.1, 0.2, 0.3]).unwrap();
            view.clip = clip;
            let fast = ev.render(&view);
            let twin = reference(
                &occlusion::emission_absorption::prepare(&data),
                &vol,
                &tf(),
                &view,
            );
            let mut worst = 0.0f64;
            for (g, c) in fast.iter().zip(&twin) {
                for k in 0..4 {
                    worst = worst.max((g[k] as f64 - c[k]).abs());
                }
            }
            // f32 against f64: the GPU's tolerance against the same twin.
            assert!(worst < 2e-3, "CPU renderer and twin differ by {worst}");
            let centre = twin[24 + 48 * 20];
            assert!(centre[3] > 0.2, "centre alpha {}", centre[3]);
        }
    }

    /// Whether this CPU marches in lanes (else both marches are the scalar one: said, and the
    /// lanes tests end there).
    #[cfg(target_arch = "x86_64")]
    fn lanes_here() -> bool {
        let here = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
        if !here {
            eprintln!("no AVX2/FMA on this CPU: both marches are the scalar one");
        }
        here
    }

    /// Four pixels' rays at once (`EaVolume::rays4`) are the scalar setup's, field for field
    /// and bit for bit: perspective and orthographic views from several sides, a camera
    /// inside the grid, views along an axis (rays parallel to two of them: the scalar code's
    /// lanes) and pixels off the grid (empty rays), at sub-pixel positions.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn four_rays_at_once_are_the_scalar_rays_bit_for_bit() {
        if !lanes_here() {
            return;
        }
        let vol = blob([40, 44, 30]);
        let data = vol.select(None).unwrap().data;
        let ev = EaVolume::new(&vol, &data, &tf()).unwrap();
        let b = vol.bounds();
        let centre = (b[0] + b[1]) * 0.5;
        let mut cams = vec![];
        for (az, el, dist) in [(30.0, 20.0, 2.5), (-150.0, -35.0, 1.6), (90.0, 0.0, 3.0)] {
            cams.push(Camera::orbit(b, az, el, dist, Some(40.0)));
            cams.push(Camera::orbit(b, az, el, dist, None));
        }
        // Straight down an axis (orthographic: every ray parallel to x and y), and a camera
        // inside the grid.
        cams.push(Camera::orbit(b, 0.0, 89.9999999, 2.0, None));
        cams.push(Camera::orbit(b, 0.0, 0.0, 2.0, None));
        let inside = Camera::look_at(
            centre + DVec3::new(1.0, -2.0, 0.5),
            centre + DVec3::new(20.0, 3.0, 1.0),
            DVec3::Z,
            occlusion::camera::Projection::Perspective { fov_y_deg: 60.0 },
            b,
        )
        .unwrap();
        cams.push(inside);
        let (mut odd, mut empty, mut full) = (0, 0, 0);
        for cam in cams {
            let (w, h) = (37u32, 29u32);
            let view = EaView::new(&vol, cam, w, h, None, None, [1.0; 3]).unwrap();
            let inv = view.camera.view_projection(w as f64 / h as f64).inverse();
            let f = view.camera.forward();
            for py in 0..h {
                for x0 in (0..w - 4).step_by(3) {
                    let y = py as f64 + 0.37;
                    let xs =
                        std::array::from_fn(|i| (x0 as usize + i) as f64 + 0.5 + 0.1 * i as f64);
                    let mut four = vec![];
                    // SAFETY: the CPU has AVX2 and FMA (checked above).
                    unsafe { ev.rays4(&view, &inv, f, xs, y, &mut four, 7) };
                    assert_eq!(
                        four.iter().map(|(i, _)| *i).collect::<Vec<_>>(),
                        [7, 8, 9, 10]
                    );
                    for ((_, r), &x) in four.iter().zip(&xs) {
                        let (o, d) = pixel_ray(&inv, &view, [x, y]);
                        let want = ev.start_along(&view, f, o, d);
                        let bits = |r: &Ray| {
                            let mut v: Vec<u64> = [r.o, r.d]
                                .iter()
                                .flat_map(|p| p.to_array())
                                .chain([r.cosine, r.o_depth])
                                .map(f64::to_bits)
                                .collect();
                            v.extend(
                                r.qa.iter()
                                    .chain(&r.dq)
                                    .chain([&r.seg, &r.front])
                                    .map(|x| x.to_bits() as u64),
                            );
                            v.extend([r.k as u64, r.k1 as u64]);
                            v
                        };
                        assert_eq!(bits(r), bits(&want), "pixel ({x}, {y})");
                        if r.k > r.k1 {
                            empty += 1;
                        } else {
                            full += 1;
                        }
                        // A ray along an axis (the scalar code's lanes).
                        if r.k <= r.k1 && r.dq.iter().any(|q| q.abs() < 1e-12) {
                            odd += 1;
                        }
                    }
                }
            }
        }
        assert!(
            empty > 100 && full > 1000 && odd > 100,
            "{empty} {full} {odd}"
        );
    }

    /// The frame of `view` with the lanes and with the scalar march, asserted equal bit for
    /// bit (image, volumetric AOV, half-opacity depth); the lanes' frame.
    #[cfg(target_arch = "x86_64")]
    fn lanes_equal_scalar(
        ev: &mut EaVolume,
        view: &EaView,
        light: Option<&LightSettings>,
    ) -> Frame {
        ev.lanes = true;
        let lanes = ev.render_frame(view, light);
        ev.lanes = false;
        let scalar = ev.render_frame(view, light);
        let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        let flat = |x: &[[f32; 4]]| x.iter().flatten().copied().collect::<Vec<_>>();
        assert_eq!(bits(&flat(&lanes.image)), bits(&flat(&scalar.image)));
        assert_eq!(bits(&lanes.volumetric), bits(&scalar.volumetric));
        assert_eq!(bits(&lanes.half_depth), bits(&scalar.half_depth));
        lanes
    }

    #[test]
    fn an_opaque_ray_shows_its_medium_not_the_background() {
        // A dense uniform medium (extinction 5 a unit, grey 0.2) before a white background: the
        // exact pixel is 0.2; a ray ended at OPAQUE takes the rest as the mean of what it
        // showed, where the background through the rest gave 0.2 + 0.8 (1 - alpha) (0.205).
        let mut vol = blob([41, 41, 41]);
        vol.fields[0].data.iter_mut().for_each(|v| *v = 0.5);
        let data = vol.select(None).unwrap().data;
        let grey = Transfer {
            points: vec![(0.0, [0.2; 3], 5.0), (1.0, [0.2; 3], 5.0)],
            rows: vec![],
        };
        let mut ev = EaVolume::new(&vol, &data, &grey).unwrap();
        let cam = Camera::orbit(vol.bounds(), 0.0, 0.0, 3.0, None);
        let view = EaView::new(&vol, cam, 33, 33, None, None, [1.0; 3]).unwrap();
        for lanes in [true, false] {
            ev.lanes = lanes;
            let p = ev.render_frame(&view, None).image[16 * 33 + 16];
            assert!(p[3] >= 0.9999, "lanes {lanes}: opacity {}", p[3]);
            for x in &p[..3] {
                assert!((x - 0.2).abs() < 1e-3, "lanes {lanes}: {x} against 0.2");
            }
        }
    }

    #[test]
    fn light_below_dark_passes_on_within_dark_of_the_full_sweep() {
        // A dense blob: deep in it the light falls below DARK, where the sweep stops sampling
        // (occlusion::combined::DARK). Against the sweep that samples every cell, each stored
        // light may be brighter, by less than DARK; and the skip is taken, alike in the lanes
        // and the scalar sweep (where the CPU has no AVX2 and FMA both runs are the scalar
        // sweep: `lanes_here` says so).
        let vol = blob([40, 44, 30]);
        let data = vol.select(None).unwrap().data;
        let dense = Transfer {
            points: vec![
                (0.05, [1.0; 3], 0.0),
                (0.3, [1.0; 3], 2.0),
                (1.0, [1.0; 3], 4.0),
            ],
            rows: vec![],
        };
        let mut ev = EaVolume::new(&vol, &data, &dense).unwrap();
        let dark = occlusion::combined::DARK;
        let cam = Camera::orbit(vol.bounds(), 40.0, 25.0, 2.5, Some(40.0));
        let view = EaView::new(&vol, cam, 48, 40, None, None, [1.0; 3]).unwrap();
        let inv = view.camera.view_projection(48.0 / 40.0).inverse();
        #[cfg(target_arch = "x86_64")]
        lanes_here();
        for (step, cone) in [(1, false), (8, false), (2, true)] {
            let light = LightSettings {
                cell: 2,
                step,
                cone,
                theta_deg: 30.0,
                blur_samples: 3,
            };
            let mut swept = vec![];
            for lanes in [true, false] {
                ev.lanes = lanes;
                let View::F32(d) = ev.data.view() else {
                    panic!("f32 samples expected")
                };
                let skip = ev.sweep(&view, d, &light, inv).values().to_vec();
                let full = ev
                    .sweep_until_dark(&view, d, &light, inv, 0.0)
                    .values()
                    .to_vec();
                let (mut worst, mut skipped, mut lit) = (0.0f32, 0, 0);
                for (&s, &f) in skip.iter().zip(&full) {
                    // (The cone model's blur widens with the shadow's age, which the skip
                    // changes too: there only the bound.)
                    assert!(
                        cone || s >= f,
                        "step {step}: skipped light {s} darker than {f}"
                    );
                    worst = worst.max((s - f).abs());
                    skipped += (s != f) as usize;
                    lit += (f > 2.0 * dark) as usize;
                }
                assert!(worst < dark, "step {step}: light moved by {worst}");
                // (Steps of 8 store a front every eight slices: 386 values skipped there.)
                let least = if step == 8 { 250 } else { 1000 };
                assert!(
                    skipped > least,
                    "step {step}: {skipped} light values skipped"
                );
                assert!(lit > 1000, "step {step}: {lit} values lit");
                swept.push(skip);
            }
            assert_eq!(swept[0], swept[1], "step {step}: lanes and scalar differ");
        }
    }

    #[test]
    fn a_sample_takes_the_light_at_its_own_depth() {
        // A uniform medium (extinction 0.1 a unit) seen face on through 40 units, in slabs 5
        // deep (sigma d = 0.5), lit by a cone of 45 degrees. The continuous model's light at
        // depth z is the mean over the cone's directions of exp(-sigma z / cos(phi)), and the
        // volumetric AOV - the opacity-weighted mean light - is its mean against the eye's
        // weights sigma exp(-sigma z) over [0, L]; with the light carried along the ray and
        // weighted by the eye within each slab (`occlusion::combined::light_in_slab`) and
        // its path through a slab the cone's mean (`cone_path_factor`) the renderer is within
        // 1% of it (0.3% measured; the light at each slab's middle is 3.4% too dark, and the
        // chord between stored slices read before passed within 2%). Either missing fails: the
        // paper's light at the slab's front is
        // exp(sigma d / 2) = 1.28 times too bright in each slab (1.2 times the AOV), and the
        // light crossing each slab straight along the ray gives (1 + exp(-sigma L)) / 2, 1.09
        // times it.
        let mut vol = blob([41, 41, 41]);
        vol.fields[0].data.iter_mut().for_each(|v| *v = 0.5);
        let data = vol.select(None).unwrap().data;
        let b = vol.bounds();
        let sigma = 0.1;
        let flat = Transfer {
            points: vec![(0.0, [1.0; 3], sigma), (1.0, [1.0; 3], sigma)],
            rows: vec![],
        };
        let ev = EaVolume::new(&vol, &data, &flat).unwrap();
        let cam = Camera::orbit(b, 0.0, 0.0, 3.0, Some(20.0));
        let view = EaView::new(&vol, cam, 33, 33, None, Some(5.0), [1.0; 3]).unwrap();
        let theta: f64 = 45.0;
        let l = b[1].y - b[0].y;
        // The continuous model: directions uniform in solid angle (cos(phi) uniform on
        // [cos(theta), 1]), each a path 1 / cos(phi) times the depth.
        let aov = |slant: f64| {
            let a = 1.0 + slant;
            (1.0 - (-a * sigma * l).exp()) / a / (1.0 - (-sigma * l).exp())
        };
        let c = theta.to_radians().cos();
        let n = 4000;
        let want = (0..n)
            .map(|i| aov(1.0 / (1.0 - (1.0 - c) * (i as f64 + 0.5) / n as f64)))
            .sum::<f64>()
            / n as f64;
        // A step a slice re-reads the light every slab; steps of 2 and 8 carry it along the
        // ray through 2 and 8 slabs (8: the whole medium) - the same light.
        for step in [1, 2, 8] {
            let light = LightSettings {
                cell: 1,
                step,
                cone: false,
                theta_deg: theta,
                blur_samples: 3,
            };
            let frame = ev.render_frame(&view, Some(&light));
            let got = frame.volumetric[16 * 33 + 16] as f64;
            assert!(
                (got - want).abs() < 0.01 * want,
                "step {step}: volumetric AOV {got} against {want} (L = {l})"
            );
        }
        assert!(aov(1.0) > 1.08 * want, "{} against {want}", aov(1.0));
    }

    #[test]
    fn a_dense_surface_shows_the_same_light_wherever_it_lies_between_the_slices() {
        // A dense slab (extinction 20 a unit past a threshold of the value, which rises from 0
        // to 1 over one voxel at its faces) seen at 10 degrees from its normal with the head
        // light, steps of eight slices half a voxel apart (four parts a voxel deep), cells of
        // 2 pixels: the face cuts the slices, parts and cells at a slant, and moving the
        // threshold moves it within the voxel. Carried along the eye's ray, the light shows
        // every pixel of the face lit by 1 / (1 + f) of the light reaching it
        // (`occlusion::combined::light_in_slab`), whatever the threshold. Read between the
        // stored parts (umbra a73110e), a face pixel lay 0.39 from 1 / (1 + f) at the first
        // threshold: the hatch of docs/accuracy.md, "A hatch on dense surfaces".
        let mut vol = blob([41, 41, 41]);
        for k in 0..41 {
            for j in 0..41 {
                for i in 0..41 {
                    let at = vol.index(i, j, k);
                    vol.fields[0].data[at] = if (12..=28).contains(&j) { 1.0 } else { 0.0 };
                }
            }
        }
        let data = vol.select(None).unwrap().data;
        let b = vol.bounds();
        let cam = Camera::orbit(b, 10.0, 0.0, 3.0, Some(20.0));
        let view = EaView::new(&vol, cam, 65, 65, None, Some(0.5), [1.0; 3]).unwrap();
        let theta = 25.0;
        let want = 1.0 / (1.0 + occlusion::combined::cone_path_factor(theta));
        for v0 in [0.1, 0.3, 0.5, 0.7, 0.9] {
            let step = Transfer {
                points: vec![
                    (0.0, [1.0; 3], 0.0),
                    (v0, [1.0; 3], 0.0),
                    (v0 + 1e-3, [1.0; 3], 20.0),
                    (1.0, [1.0; 3], 20.0),
                ],
                rows: vec![],
            };
            let ev = EaVolume::new(&vol, &data, &step).unwrap();
            let frame = ev.render_frame(&view, Some(&paper_light(8, theta)));
            // The face's middle: 21 x 21 pixels, all opaque.
            let face: Vec<usize> = (22..43)
                .flat_map(|y| (22..43).map(move |x| y * 65 + x))
                .collect();
            assert!(
                face.iter().all(|&p| frame.image[p][3] > 0.99),
                "{v0}: opaque"
            );
            let worst = face
                .iter()
                .map(|&p| (frame.volumetric[p] as f64 - want).abs())
                .fold(0.0, f64::max);
            assert!(
                worst < 0.02 * want,
                "threshold {v0}: the face's light {worst} from {want} at most"
            );
        }
    }

    #[test]
    fn a_light_a_voxel_deep_shades_as_the_light_a_slice_deep() {
        // Steps of two and four slices (slices a quarter voxel apart: a step of four is a
        // voxel) against the light of every slice, both models: the volumetric occlusion
        // moves by little in mean and the image by less than a level, but it does move (the
        // sweep took the steps).
        let vol = blob([40, 44, 30]);
        let data = vol.select(None).unwrap().data;
        let b = vol.bounds();
        let ev = EaVolume::new(&vol, &data, &tf()).unwrap();
        let cam = Camera::orbit(b, 40.0, 25.0, 2.5, Some(40.0));
        let view = EaView::new(&vol, cam, 64, 48, None, Some(0.25), [1.0; 3]).unwrap();
        for cone in [false, true] {
            let light = |step| LightSettings {
                cell: 2,
                step,
                cone,
                theta_deg: 25.0,
                blur_samples: 3,
            };
            let fine = ev.render_frame(&view, Some(&light(1)));
            let shadowed = fine.volumetric.iter().filter(|&&o| o < 0.9).count();
            assert!(shadowed > 100, "{shadowed} shadowed pixels");
            for step in [2, 4] {
                let coarse = ev.render_frame(&view, Some(&light(step)));
                let n = fine.volumetric.len() as f64;
                let dv: f64 = fine
                    .volumetric
                    .iter()
                    .zip(&coarse.volumetric)
                    .map(|(a, b)| (a - b).abs() as f64)
                    .sum::<f64>()
                    / n;
                let di: f64 = fine
                    .image
                    .iter()
                    .zip(&coarse.image)
                    .map(|(a, b)| (0..3).map(|c| (a[c] - b[c]).abs()).fold(0.0, f32::max) as f64)
                    .sum::<f64>()
                    / n;
                assert!(
                    dv > 1e-5,
                    "cone {cone} step {step}: the light did not change"
                );
                assert!(
                    dv < 0.01,
                    "cone {cone} step {step}: occlusion moved by {dv} in mean"
                );
                assert!(
                    di < 1.0 / 255.0,
                    "cone {cone} step {step}: image moved by {di}"
                );
            }
        }
    }

    #[test]
    fn a_deep_light_step_takes_the_samples_of_the_steps_a_voxel_deep() {
        // Slices 0.2 apart, the smallest spacing 40 / 43: a voxel is four slices (the
        // largest power of two within it). A step of eight slices takes
        // two samples, at the middles of its halves - the samples of the two steps a voxel
        // deep it spans - so its optical depth is theirs, clipped or not, and with the camera
        // inside the grid (parts behind the eye unsampled, a step's parts ahead of it sampled).
        let vol = blob([40, 44, 30]);
        let data = vol.select(None).unwrap().data;
        let b = vol.bounds();
        let ev = EaVolume::new(&vol, &data, &tf()).unwrap();
        let View::F32(data) = ev.data.view() else {
            panic!("f32 samples expected")
        };
        let outside = Camera::orbit(b, 40.0, 25.0, 2.5, Some(40.0));
        // At the grid's centre, the near plane (the rays' origins) 2.6 deep: the slices start
        // at the eye, so the first steps (1.6 deep) lie behind the origins, and the second's
        // middle (2.4) too but not its second part's (2.8).
        let mut inside = outside;
        inside.eye = 0.5 * (b[0] + b[1]);
        inside.target = inside.eye + (outside.target - outside.eye);
        inside.near = 2.6;
        // A plane through the middle of the grid, tilted to the slices.
        let n = DVec3::new(0.3, -0.5, 0.8);
        let plane = ([n.x, n.y, n.z], (0.5 * (b[0] + b[1])).dot(n));
        let mut behind = 0;
        for (cam, clip) in [
            (outside, vec![]),
            (outside, vec![plane]),
            (inside, vec![]),
            (inside, vec![plane]),
        ] {
            let mut view = EaView::new(&vol, cam, 32, 24, None, Some(0.2), [1.0; 3]).unwrap();
            view.clip = clip.clone();
            let vs = occlusion::combined::voxel_step(&view);
            assert_eq!(vs, 4);
            assert_eq!(occlusion::combined::light_samples(&view, 8), 2);
            let (fine, coarse) = (
                occlusion::combined::light_view(&view, vs),
                occlusion::combined::light_view(&view, 8),
            );
            let inv = view.camera.view_projection(32.0 / 24.0).inverse();
            let (mut checked, mut nonzero) = (0, 0);
            for py in 0..24 {
                for px in 0..32 {
                    let (o, d) = pixel_ray(&inv, &view, [px as f64 + 0.5, py as f64 + 0.5]);
                    let (rf, rc) = (ev.start(&fine, o, d), ev.light_start(&coarse, o, d, 2));
                    behind += (rc.front > 0.5) as usize;

                    for k in 0..coarse.slices {
                        let (parts, next) = ev.optical_depth(&coarse, data, &rc, k, 2);
                        for (i, &deep) in parts.iter().enumerate() {
                            let a = match i {
                                0 | 1 => {
                                    ev.optical_depth(&fine, data, &rf, 2 * k + i as u32, 1).0[0]
                                }
                                _ => 0.0,
                            };
                            assert!(
                                (deep - a).abs() <= 1e-4 * a + 1e-6,
                                "clip {}: pixel ({px}, {py}) step {k} part {i}: {deep} against {a}",
                                !clip.is_empty()
                            );
                        }
                        let deep = parts[0] + parts[1];
                        // The next step to sample never passes a sample with depth.
                        if next > k + 1 && next != u32::MAX {
                            for j in k + 1..next.min(coarse.slices) {
                                assert_eq!(ev.optical_depth(&coarse, data, &rc, j, 2).0, [0.0; 8]);
                            }
                        }
                        checked += 1;
                        nonzero += (deep > 0.0) as usize;
                    }
                }
            }
            assert!(nonzero > 100, "{nonzero} of {checked} steps with depth");
        }
        assert!(behind > 100, "{behind} rays start behind the slices' front");
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn eight_lanes_march_as_the_scalar_march_bit_for_bit_lit_or_not() {
        if !lanes_here() {
            return;
        }
        let vol = blob([40, 44, 30]);
        let data = vol.select(None).unwrap().data;
        let b = vol.bounds();
        // A step (two points at one value), extinction below the first point, one point.
        let step = Transfer {
            points: vec![
                (0.05, [0.3, 0.3, 0.3], 0.2),
                (0.4, [0.1, 0.9, 0.2], 0.5),
                (0.4, [0.9, 0.1, 0.2], 2.0),
                (0.8, [1.0, 1.0, 1.0], 6.0),
            ],
            rows: vec![],
        };
        // One point, thin enough for every ray to reach the NaN hole (a gap, not a sample).
        let single = Transfer {
            points: vec![(0.5, [0.7, 0.2, 0.1], 0.01)],
            rows: vec![],
        };
        let (mut marched, mut halves, mut shadowed) = (0, 0, 0);
        for (tf, in_place) in [(tf(), false), (step, false), (single, false), (tf(), true)] {
            let mut ev = match in_place {
                false => EaVolume::new(&vol, &data, &tf).unwrap(),
                true => {
                    EaVolume::in_place(&vol, Arc::new(Samples::pack(prepare(&data))), &tf).unwrap()
                }
            };
            assert_eq!(ev.bricks.is_none(), in_place);
            for cam in [
                Camera::orbit(b, 40.0, 25.0, 2.5, Some(40.0)),
                Camera::orbit(b, -70.0, 60.0, 3.0, None),
                Camera::orbit(b, 10.0, -30.0, 1.01, Some(70.0)),
                // Along an axis: rays with direction components of zero.
                Camera::orbit(b, 0.0, 0.0, 2.0, None),
                Camera::orbit(b, 90.0, 90.0, 2.0, Some(30.0)),
                // Inside the grid, the rays' origins past the first slices (the light's
                // parts behind them unsampled).
                inside_camera(b),
            ] {
                let view = EaView::new(&vol, cam, 37, 29, None, None, [0.1, 0.2, 0.3]).unwrap();
                // Unlit (`ea`) and with the occlusion buffer (`combined`'s eye march).
                let light = paper_light(1, 25.0);
                // Light steps of two slices: the march carries the light two slabs; of eight: the
                // sweep takes four samples a step (a voxel apart).
                let stepped = LightSettings { step: 2, ..light };
                let deep = LightSettings { step: 8, ..light };
                for light in [None, Some(&light), Some(&stepped), Some(&deep)] {
                    let lanes = lanes_equal_scalar(&mut ev, &view, light);
                    marched += lanes.image.iter().filter(|p| p[3] > 0.0).count();
                    halves += lanes.half_depth.iter().filter(|&&z| z != 0.0).count();
                    shadowed += lanes.volumetric.iter().filter(|&&o| o < 0.99).count();
                }
            }
        }
        assert!(marched > 1000, "{marched} pixels with volume");
        assert!(halves > 100, "{halves} pixels past half opacity");
        assert!(shadowed > 100, "{shadowed} pixels in the volume's shadow");
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn eight_lanes_gather_narrow_and_unbricked_samples_as_the_scalar_march() {
        // Integer samples stored in u8 and u16 (plus an offset): the lanes read them as 32-bit
        // words ending at the sample (never past the buffer), shifted and masked; bricked, and
        // in the grid's own layout (large volumes are read where they are).
        if !lanes_here() {
            return;
        }
        let vol = blob([33, 41, 27]);
        let blob_data = vol.select(None).unwrap().data;
        let b = vol.bounds();
        let light = LightSettings {
            cell: 3,
            step: 1,
            cone: false,
            theta_deg: 25.0,
            blur_samples: 3,
        };
        for (scale, offset, storage) in [(200.0f32, 17.0f32, "u8"), (3000.0, 1000.0, "u16")] {
            let data: Vec<f32> = blob_data
                .iter()
                .map(|&x| {
                    if x.is_finite() {
                        (x * scale).round() + offset
                    } else {
                        offset
                    }
                })
                .collect();
            let s = scale as f64;
            let o = offset as f64;
            let tf = Transfer {
                points: vec![
                    (0.1 * s + o, [0.0, 0.0, 0.0], 0.0),
                    (0.5 * s + o, [0.2, 0.4, 1.0], 0.3),
                    (0.9 * s + o, [1.0, 0.6, 0.2], 0.9),
                ],
                rows: vec![],
            };
            // Bricked (a copy), and read where the samples are (the grid's layout).
            let bricked = EaVolume::with_storage(&vol, &data, &tf, true).unwrap();
            let flat =
                EaVolume::in_place(&vol, Arc::new(Samples::pack(data.clone())), &tf).unwrap();
            for mut ev in [bricked, flat] {
                assert_eq!(ev.storage(), storage);
                for cam in [
                    Camera::orbit(b, 40.0, 25.0, 2.5, Some(40.0)),
                    Camera::orbit(b, -120.0, -50.0, 3.0, None),
                ] {
                    let view = EaView::new(&vol, cam, 64, 48, None, None, [0.1, 0.2, 0.3]).unwrap();
                    for light in [None, Some(&light)] {
                        let lanes = lanes_equal_scalar(&mut ev, &view, light);
                        let shown = lanes.image.iter().filter(|p| p[3] > 0.1).count();
                        assert!(shown > 100, "{storage}: {shown} pixels shown");
                    }
                }
            }
        }
    }

    #[test]
    fn empty_bricks_are_stepped_over_exactly_up_to_a_hard_edge() {
        // A cube of `top` from voxel 24 (a brick's first voxel) to 39 in zeros: a ray leaving
        // the empty blocks meets opaque data at once, so a step one slice too far shows; the
        // empty margin is five skip blocks deep, so rays cross cubes of several blocks at a
        // step. Ones are stored as bytes, 1000 as u16, both exactly; f32 by default.
        let n = 64;
        for (top, storage) in [(1.0f32, "u8"), (1000.0, "u16")] {
            let mut data = vec![0.0f32; n * n * n];
            for k in 24..40 {
                for j in 24..40 {
                    for i in 24..40 {
                        data[i + n * (j + n * k)] = top;
                    }
                }
            }
            let field = Field {
                name: "cube".into(),
                components: 1,
                stored: ScalarType::F32,
                data: data.clone(),
            };
            let vol = Volume::new([n; 3], DMat4::IDENTITY, Space::File, field).unwrap();
            let tf = Transfer::ramp(0.0, top as f64, [1.0, 0.5, 0.2], 0.8);
            let ev = EaVolume::with_storage(&vol, &data, &tf, true).unwrap();
            assert_eq!(ev.storage(), storage);
            assert!(
                ev.reach.iter().any(|&r| r >= 4),
                "the test needs deep empty cubes"
            );
            assert_eq!(EaVolume::new(&vol, &data, &tf).unwrap().storage(), "f32");
            let b = vol.bounds();
            for cam in [
                Camera::orbit(b, 33.0, 21.0, 2.5, Some(35.0)),
                Camera::orbit(b, 0.0, 0.0, 2.5, None),
            ] {
                let view = EaView::new(&vol, cam, 40, 40, None, None, [1.0; 3]).unwrap();
                let fast = ev.render(&view);
                let twin = reference(&prepare(&data), &vol, &tf, &view);
                let worst = fast
                    .iter()
                    .zip(&twin)
                    .flat_map(|(g, c)| (0..4).map(move |k| (g[k] as f64 - c[k]).abs()))
                    .fold(0.0, f64::max);
                assert!(worst < 2e-3, "{storage}: {worst}");
            }
        }
    }

    /// The light volume kept from one frame for the next (`light_store`) leaves nothing
    /// behind: after frames of other views, sizes and slice counts, a lit frame is bit for bit
    /// the frame of a volume that drew nothing before.
    #[test]
    fn a_lit_frame_is_the_same_after_other_frames() {
        let dims = [29, 23, 19];
        let blob = blob(dims);
        let data: Vec<f32> = blob.fields[0]
            .data
            .iter()
            .map(|v| if v.is_nan() { 0.0 } else { *v })
            .collect();
        let field = Field {
            name: "f".into(),
            components: 1,
            stored: ScalarType::F32,
            data: data.clone(),
        };
        let vol = Volume::new(dims, blob.affine, Space::File, field).unwrap();
        let tf = Transfer::ramp(0.1, 0.9, [1.0, 0.8, 0.6], 3.0);
        let view_at = |az: f64, dist: f64, w: u32, h: u32, slices: Option<u32>| {
            let cam = Camera::orbit(vol.bounds(), az, 25.0, dist, Some(40.0));
            EaView::new(&vol, cam, w, h, slices, None, [1.0; 3]).unwrap()
        };
        let view = |az: f64, w: u32, h: u32, slices: Option<u32>| view_at(az, 2.0, w, h, slices);
        // 57 slices: the last block of KB slices is partly used.
        let unclipped = view(30.0, 40, 30, Some(57));
        let bounds = vol.bounds();
        // The cone model, the paper's blur on narrow stencils (the row path) and on wide ones;
        // steps of a slice and of eight (a front stored a step; behind a clipping plane, the
        // stored slices past a step's first too, attenuated).
        for (cone, theta_deg, step, clipped) in [
            (true, 30.0, 1, false),
            (false, 30.0, 1, false),
            (false, 80.0, 1, false),
            (false, 30.0, 8, false),
            (false, 30.0, 8, true),
        ] {
            let mut target = unclipped.clone();
            if clipped {
                target.clip = vec![([1.0, 0.0, 0.0], 0.25 * bounds[0].x + 0.75 * bounds[1].x)];
            }
            let light = LightSettings {
                cell: 2,
                step,
                cone,
                theta_deg,
                blur_samples: 3,
            };
            let wide = occlusion::combined::blur_rows(&target, 2, theta_deg)
                .iter()
                .filter(|r| r.wide)
                .count();
            assert_eq!(wide > 0, theta_deg > 45.0, "theta {theta_deg}: {wide} wide");
            let samples = occlusion::combined::light_samples(&target, step);
            assert_eq!(
                samples > 1,
                step > 1,
                "step {step}: {samples} samples a step"
            );
            let fresh = EaVolume::new(&vol, &data, &tf).unwrap();
            let want = fresh.render_frame(&target, Some(&light));
            assert!(want.image.iter().any(|p| p[3] > 0.3), "an opaque part");
            // The light volume kept (every value, read by the frame or not).
            let kept = |ev: &EaVolume| ev.light_store.lock().unwrap().clone();
            let want_light = kept(&fresh);
            assert!(want_light.iter().any(|&o| o < 0.5), "a dark part");
            // The same frame whatever the threads sharing the sweep's slices.
            for threads in [1, 4] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let ev = EaVolume::new(&vol, &data, &tf).unwrap();
                let got = pool.install(|| ev.render_frame(&target, Some(&light)));
                assert!(
                    got.image == want.image && got.volumetric == want.volumetric,
                    "{threads} threads, cone {cone}, theta {theta_deg}"
                );
            }
            let ev = EaVolume::new(&vol, &data, &tf).unwrap();
            // Frames within twice the target's light volume (a larger one's memory is dropped).
            let others = [
                // The target's layout, nearer.
                view_at(30.0, 1.3, 40, 30, Some(57)),
                view(200.0, 40, 30, Some(64)),
                view(120.0, 48, 36, Some(80)),
                view(300.0, 36, 26, Some(50)),
            ];
            for other in others {
                ev.render_frame(&other, Some(&light));
                let got = ev.render_frame(&target, Some(&light));
                assert!(
                    got.image == want.image && got.volumetric == want.volumetric,
                    "cone {cone}, theta {theta_deg}, step {step}, clipped {clipped}"
                );
                assert!(
                    kept(&ev) == want_light,
                    "light volume: cone {cone}, theta {theta_deg}, step {step}, clipped {clipped}"
                );
            }
        }
    }

    #[test]
    fn bricks_are_copied_straight_in_the_samples_type_as_through_f32() {
        // u8 and u16 samples with and without an offset, and f32 samples packed narrow (the
        // `with_storage` route): the bricks equal the route through an f32 copy, word for word.
        let dims = [19, 11, 7];
        let n: usize = dims.iter().product();
        let bricks = dims.map(|d: usize| d.saturating_sub(1).max(1).div_ceil(BRICK));
        for (lo, span) in [
            (0.0f32, 200.0f32),
            (-128.0, 250.0),
            (-1024.0, 3000.0),
            (0.0, 60000.0),
        ] {
            let data: Vec<f32> = (0..n)
                .map(|i| lo + ((i * 7919) % (span as usize + 1)) as f32)
                .collect();
            let packed = Samples::pack(data.clone());
            assert_ne!(
                packed.packing(),
                Packing::F32,
                "the test needs narrow samples"
            );
            let want = Samples::pack_as(bricked(&data, dims, bricks, |v| v), packed.packing());
            assert_eq!(bricks_of(&packed, dims, bricks, packed.packing()), want);
            let f32s = Samples::f32(data.clone());
            assert_eq!(bricks_of(&f32s, dims, bricks, packed.packing()), want);
        }
    }

    #[test]
    fn shared_samples_in_their_stored_type_render_as_a_copy_in_bricks() {
        // A CT-like int16 volume: integers from -1024 (air) up, packed as u16 above -1024.
        let dims = [29, 23, 19];
        let blob = blob(dims);
        let data: Vec<f32> = blob.fields[0]
            .data
            .iter()
            .map(|&v| {
                if v.is_nan() {
                    -1024.0
                } else {
                    (v * 2500.0).round() - 1024.0
                }
            })
            .collect();
        let field = Field {
            name: "ct".into(),
            components: 1,
            stored: ScalarType::I16,
            data: data.clone(),
        };
        let vol = Volume::new(dims, blob.affine, Space::File, field).unwrap();
        let tf = Transfer::ramp(-500.0, 1476.0, [1.0, 0.8, 0.6], 0.6);
        let packed = Arc::new(Samples::pack(data.clone()));
        assert_eq!(packed.packing(), Packing::U16 { offset: -1024.0 });
        let shared = EaVolume::in_place(&vol, packed.clone(), &tf).unwrap();
        assert!(Arc::ptr_eq(&shared.data, &packed), "not copied");
        assert_eq!((shared.storage(), shared.bricks), ("u16", None));
        let copy = EaVolume::new(&vol, &data, &tf).unwrap();
        assert_eq!(copy.storage(), "f32");
        assert!(copy.bricks.is_some());
        let small = EaVolume::shared(&vol, packed.clone(), &tf).unwrap();
        assert!(small.bricks.is_some(), "small volumes are copied to bricks");
        assert_eq!(
            small.storage(),
            "u16",
            "the copy keeps the samples' packing"
        );
        let cam = Camera::orbit(vol.bounds(), 25.0, 35.0, 2.0, Some(45.0));
        let view = EaView::new(&vol, cam, 32, 24, None, None, [1.0; 3]).unwrap();
        let light = paper_light(1, 25.0);
        let diff = |a: &[[f32; 4]], b: &[[f32; 4]]| {
            a.iter()
                .zip(b)
                .flat_map(|(g, c)| (0..4).map(move |k| (g[k] - c[k]).abs()))
                .fold(0.0f32, f32::max)
        };
        let (a, b) = (shared.render(&view), copy.render(&view));
        assert!(
            a.iter().any(|p| p[3] > 0.3),
            "the test needs an opaque part"
        );
        assert!(diff(&a, &b) < 1e-5, "ea: {}", diff(&a, &b));
        let (a, b) = (
            shared.render_frame(&view, Some(&light)).image,
            copy.render_frame(&view, Some(&light)).image,
        );
        assert!(diff(&a, &b) < 1e-5, "lit: {}", diff(&a, &b));
        let (a, b) = (
            shared.render_projection(&view, Extremum::Max).image,
            copy.render_projection(&view, Extremum::Max).image,
        );
        assert!(diff(&a, &b) < 1e-5, "mip: {}", diff(&a, &b));
        // The bricked copy in u16 as the f32 copy, lit or not.
        for light in [None, Some(&light)] {
            let (a, b) = (
                small.render_frame(&view, light).image,
                copy.render_frame(&view, light).image,
            );
            assert!(diff(&a, &b) < 1e-5, "u16 bricks: {}", diff(&a, &b));
        }
        let twin = reference(&data, &vol, &tf, &view);
        let worst = shared
            .render(&view)
            .iter()
            .zip(&twin)
            .flat_map(|(g, c)| (0..4).map(move |k| (g[k] as f64 - c[k]).abs()))
            .fold(0.0, f64::max);
        assert!(worst < 2e-3, "against the twin: {worst}");
    }

    #[test]
    fn samples_read_in_place_on_grids_one_sample_thick_repeat_the_last_sample() {
        // A single slice (a 2-D image), a single column and a single row: along an axis of
        // one sample a cell's far corners are its near ones, as in the bricks.
        for dims in [[4, 3, 1], [1, 3, 4], [4, 1, 3], [2, 2, 2]] {
            let n: usize = dims.iter().product();
            let field = Field {
                name: "index".into(),
                components: 1,
                stored: ScalarType::U16,
                data: (0..n).map(|i| i as f32).collect(),
            };
            let vol = Volume::new(dims, DMat4::IDENTITY, Space::File, field).unwrap();
            let data = vol.fields[0].data.clone();
            let tf = Transfer::ramp(0.0, n as f64, [1.0; 3], 1.0);
            let flat =
                EaVolume::in_place(&vol, Arc::new(Samples::pack(data.clone())), &tf).unwrap();
            let bricked = EaVolume::new(&vol, &data, &tf).unwrap();
            // The last cell, reached at the grid's far corner.
            let q = dims.map(|d| d as f32 - 1.0);
            let (cell, _, _) = flat.cell(q);
            let want = {
                let View::F32(d) = bricked.data.view() else {
                    panic!("f32 bricks")
                };
                bricked.corners(d, cell)
            };
            let View::U8(d, _) = flat.data.view() else {
                panic!("u8 in place")
            };
            let got = flat.corners(d, cell);
            assert_eq!(got, want, "{dims:?}");
            let at = |x: usize, y: usize, z: usize| {
                let c = |v: usize, a: usize| v.min(dims[a] - 1);
                (c(x, 0) + dims[0] * (c(y, 1) + dims[1] * c(z, 2))) as f32
            };
            let [x, y, z] = cell;
            assert_eq!(
                got,
                [
                    at(x, y, z),
                    at(x + 1, y, z),
                    at(x, y + 1, z),
                    at(x + 1, y + 1, z),
                    at(x, y, z + 1),
                    at(x + 1, y, z + 1),
                    at(x, y + 1, z + 1),
                    at(x + 1, y + 1, z + 1),
                ],
                "{dims:?}"
            );
        }
    }

    #[test]
    fn grids_that_do_not_fill_their_bricks_match_the_twin() {
        for dims in [[17, 2, 11], [26, 19, 9], [9, 9, 9]] {
            let vol = blob(dims);
            let data = vol.select(None).unwrap().data;
            let ev = EaVolume::new(&vol, &data, &tf()).unwrap();
            let cam = Camera::orbit(vol.bounds(), 25.0, 35.0, 2.0, Some(45.0));
            let view = EaView::new(&vol, cam, 32, 24, None, None, [1.0; 3]).unwrap();
            let twin = reference(&prepare(&data), &vol, &tf(), &view);
            let worst = ev
                .render(&view)
                .iter()
                .zip(&twin)
                .flat_map(|(g, c)| (0..4).map(move |k| (g[k] as f64 - c[k]).abs()))
                .fold(0.0, f64::max);
            assert!(worst < 2e-3, "{dims:?}: {worst}");
        }
    }

    #[test]
    fn the_skip_reach_is_the_chebyshev_distance_to_the_nearest_occupied_block() {
        let nb = [7, 5, 6];
        let mut occ = vec![0u32; 7 * 5 * 6];
        let idx = |x: usize, y: usize, z: usize| x + 7 * (y + 5 * z);
        occ[idx(1, 1, 1)] = 1;
        occ[idx(6, 4, 5)] = 1;
        let reach = reach_of(&occ, nb);
        for z in 0..6usize {
            for y in 0..5usize {
                for x in 0..7usize {
                    let cheb = |o: [usize; 3]| {
                        [x.abs_diff(o[0]), y.abs_diff(o[1]), z.abs_diff(o[2])]
                            .into_iter()
                            .max()
                            .unwrap()
                    };
                    let want = cheb([1, 1, 1]).min(cheb([6, 4, 5]));
                    assert_eq!(reach[idx(x, y, z)] as usize, want, "{x} {y} {z}");
                }
            }
        }
        // Nothing occupied: every block keeps the cap.
        assert!(reach_of(&[0; 8], [2, 2, 2]).iter().all(|&r| r == REACH));
    }

    #[test]
    fn the_tabled_exponential_is_within_its_bound() {
        let vol = blob([8, 8, 8]);
        let data = vol.select(None).unwrap().data;
        let ev = EaVolume::new(&vol, &data, &tf()).unwrap();
        let mut worst = 0.0f64;
        for i in 0..400_000 {
            let x = i as f32 * 5e-5;
            worst = worst.max((ev.exp_neg(x) as f64 - (-(x as f64)).exp()).abs());
        }
        assert!(worst < 1e-5, "{worst}");
        assert_eq!(ev.exp_neg(0.0), 1.0);
        assert_eq!(ev.exp_neg(f32::NAN), 1.0);
        assert_eq!(ev.exp_neg(17.0), 0.0);
    }

    /// A 40 x 34 x 30 blob with NaN gaps (holes) across its shells too (every value of a
    /// window), not only its centre, and its samples.
    fn gapped_blob() -> (Volume, Vec<f32>) {
        let vol = blob([40, 34, 30]);
        let mut data = vol.select(None).unwrap().data;
        for i in (2..38).step_by(3) {
            data[vol.index(i, 17, 15)] = f32::NAN;
            data[vol.index(20, 17, i.min(29))] = f32::NAN;
        }
        (vol, data)
    }

    /// A projection marched eight rays at a time (`lanes::march_extreme`) is the scalar
    /// march's image bit for bit: maximum and minimum, a window transparent below and one
    /// turned round (empty blocks stepped over, and ending the ray), f32 samples with a NaN
    /// hole (a gap) and u8 and u16 samples in bricks and in the grid's layout, views from
    /// several sides, along an axis and from inside the grid.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn eight_lanes_project_as_the_scalar_march_bit_for_bit() {
        if !lanes_here() {
            return;
        }
        let (vol, data) = gapped_blob();
        let b = vol.bounds();
        // Integers 0..=250 (u8) and 0..=60,000 (u16) with an offset, for the narrow types.
        let ints = |scale: f32, offset: f32| -> Vec<f32> {
            data.iter()
                .map(|v| {
                    if v.is_nan() {
                        offset
                    } else {
                        (v * scale).round() + offset
                    }
                })
                .collect()
        };
        let (u8s, u16s) = (ints(250.0, 0.0), ints(60000.0, -1000.0));
        let (mut shown, mut ended, mut frames) = (0, 0, 0);
        for (samples, scale, offset, narrow) in [
            (&data, 1.0, 0.0, false),
            (&u8s, 250.0, 0.0, true),
            (&u16s, 60000.0, -1000.0, true),
        ] {
            for (lo, hi) in [(0.2, 0.9), (0.3, 0.05)] {
                let t = window_ramp(lo * scale + offset, hi * scale + offset);
                for in_place in [false, true] {
                    let mut ev = match in_place {
                        false => EaVolume::with_storage(&vol, samples, &t, narrow).unwrap(),
                        true => {
                            EaVolume::in_place(&vol, Arc::new(Samples::pack(prepare(samples))), &t)
                                .unwrap()
                        }
                    };
                    // (The f32 samples hold empty blocks on both sides of the windows.)
                    assert!(
                        narrow || ev.occupied.iter().any(|o| !o),
                        "some blocks are empty: window {lo}-{hi} in place {in_place}"
                    );
                    for cam in [
                        Camera::orbit(b, 35.0, 25.0, 2.5, Some(40.0)),
                        Camera::orbit(b, -120.0, -40.0, 3.0, None),
                        Camera::orbit(b, 0.0, 0.0, 2.0, None),
                        inside_camera(b),
                    ] {
                        let v =
                            EaView::new(&vol, cam, 37, 29, None, None, [0.1, 0.2, 0.3]).unwrap();
                        for which in [Extremum::Max, Extremum::Min] {
                            ev.lanes = true;
                            let lanes = ev.render_projection(&v, which);
                            ev.lanes = false;
                            let scalar = ev.render_projection(&v, which);
                            let bits = |f: &Frame| {
                                f.image
                                    .iter()
                                    .flatten()
                                    .map(|x| x.to_bits())
                                    .collect::<Vec<_>>()
                            };
                            assert_eq!(
                                bits(&lanes),
                                bits(&scalar),
                                "{} {which:?} window {lo}-{hi} in place {in_place}",
                                ev.storage()
                            );
                            shown += lanes.image.iter().filter(|p| p[3] > 0.0).count();
                            ended += lanes.image.iter().filter(|p| p[3] == 0.0).count();
                            frames += 1;
                        }
                    }
                }
            }
        }
        assert!(
            shown > 20 * frames && ended > 20 * frames,
            "{shown} {ended} {frames}"
        );
    }

    /// The paper's light model on cells of two pixels, steps of `step` slices, a cone of
    /// `theta_deg` degrees, three blur samples a side.
    fn paper_light(step: u32, theta_deg: f64) -> LightSettings {
        LightSettings {
            cell: 2,
            step,
            cone: false,
            theta_deg,
            blur_samples: 3,
        }
    }

    /// A blob's shell clear, its core dense (extinction 4 a unit): rays end opaque in it.
    fn dense_tf() -> Transfer {
        Transfer {
            points: vec![(0.1, [0.9, 0.5, 0.2], 0.0), (0.6, [0.2, 0.6, 1.0], 4.0)],
            rows: vec![],
        }
    }

    /// One, two and three clipping planes (faces across a grid's middle `c`, tilted to the
    /// slices), as `EaView::clip` holds them.
    fn test_planes(c: DVec3) -> [Vec<([f64; 3], f64)>; 3] {
        let plane = |n: [f64; 3], at: DVec3| (n, DVec3::from(n).dot(at));
        [
            vec![plane([1.0, 0.0, 0.0], c)],
            vec![
                plane([0.6, -0.8, 0.2], c),
                plane([-0.3, 0.1, 1.0], c + DVec3::Z * 3.0),
            ],
            vec![
                plane([0.0, 1.0, 0.0], c - DVec3::Y * 4.0),
                plane([0.0, -1.0, 0.3], c - DVec3::Y * 9.0),
                plane([1.0, 1.0, 0.0], c + DVec3::X * 5.0),
            ],
        ]
    }

    /// Clipped unlit frames - `ea` and the projections, whose rays take the slabs of their
    /// `Ray::inner` eight at a time between the scalar march's cut slabs
    /// (`EaVolume::march_clipped`) - are the scalar march's bit for bit, and so are clipped
    /// `combined` frames, whose light cells take those slabs eight at a time: one to three planes,
    /// views from several sides and from inside the grid, transfer functions that leave
    /// blocks empty on either side (a projection's transparent end), gaps, rays ending opaque.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn clipped_frames_march_in_lanes_as_the_scalar_march_bit_for_bit() {
        if !lanes_here() {
            return;
        }
        let (vol, data) = gapped_blob();
        let b = vol.bounds();
        let c = 0.5 * (b[0] + b[1]);
        let planes = test_planes(c);
        let dense = dense_tf();
        let bits = |f: &Frame| {
            let mut b: Vec<u32> = f.image.iter().flatten().map(|x| x.to_bits()).collect();
            b.extend(
                f.volumetric
                    .iter()
                    .chain(&f.half_depth)
                    .map(|x| x.to_bits()),
            );
            b
        };
        let (mut inner, mut opaque, mut ended, mut frames) = (0, 0, 0, 0);
        let (mut shadowed, mut first_only) = (0, 0);
        // Past OPAQUE (not 1) at any sample a slice deep: rays end at their first sample in
        // the grid.
        let wall = Transfer {
            points: vec![(0.0, [0.4, 0.8, 0.3], 12.0)],
            rows: vec![],
        };
        for t in [dense, wall, window_ramp(0.2, 0.9), window_ramp(0.3, 0.05)] {
            let mut ev = EaVolume::new(&vol, &data, &t).unwrap();
            // The three sets of planes, and a plane parallel to the slices 2.5 slabs behind
            // the first, keeping the front: the rays' `inner` is slice 0 alone.
            for clip in 0..4 {
                for cam in [
                    Camera::orbit(b, 35.0, 25.0, 2.5, Some(40.0)),
                    Camera::orbit(b, -120.0, -40.0, 3.0, None),
                    Camera::orbit(b, 0.0, 0.0, 2.0, None),
                    inside_camera(b),
                ] {
                    let mut v =
                        EaView::new(&vol, cam, 37, 29, None, None, [0.1, 0.2, 0.3]).unwrap();
                    v.clip = match planes.get(clip) {
                        Some(p) => p.clone(),
                        None => {
                            let f = cam.forward();
                            vec![(f.to_array(), f.dot(cam.eye) + v.z0 + 2.5 * v.dz)]
                        }
                    };
                    let inv = v.camera.view_projection(37.0 / 29.0).inverse();
                    for y in 0..29 {
                        for x in 0..37 {
                            let (o, d) = pixel_ray(&inv, &v, [x as f64 + 0.5, y as f64 + 0.5]);
                            let mut r = ev.start(&v, o, d);
                            ev.clip_slabs(&v, &mut r);
                            inner += (r.inner.0 <= r.inner.1) as usize;
                            first_only += (r.inner == (0, 0) && r.k == 0) as usize;
                        }
                    }
                    // `combined`: its light swept and its eye marched with the lanes behind
                    // the planes (the light read at the cells' shifts), a step a slice, and
                    // of eight slices sampled in parts.
                    let light = paper_light(1, 30.0);
                    let deep = LightSettings { step: 8, ..light };
                    for mode in 0..5 {
                        let frame = |ev: &EaVolume| match mode {
                            0 => ev.render_frame(&v, None),
                            1 => ev.render_projection(&v, Extremum::Max),
                            2 => ev.render_projection(&v, Extremum::Min),
                            3 => ev.render_frame(&v, Some(&light)),
                            _ => ev.render_frame(&v, Some(&deep)),
                        };
                        ev.lanes = true;
                        let lanes = frame(&ev);
                        ev.lanes = false;
                        let scalar = frame(&ev);
                        assert!(
                            bits(&lanes) == bits(&scalar),
                            "mode {mode} planes {:?} camera {cam:?}",
                            v.clip
                        );
                        if mode == 0 {
                            opaque += lanes.image.iter().filter(|p| p[3] > 0.99).count();
                        }
                        if mode >= 3 {
                            shadowed += lanes.volumetric.iter().filter(|&&o| o < 0.9).count();
                        }
                        ended += lanes.image.iter().filter(|p| p[3] == 0.0).count();
                        frames += 1;
                    }
                }
            }
        }
        assert!(
            inner > 100 * frames / 5,
            "{inner} rays with slabs behind the planes"
        );
        assert!(
            opaque > 100 && ended > 20 * frames,
            "{opaque} {ended} {frames}"
        );
        assert!(shadowed > 1000, "{shadowed} pixels in the light's shadow");
        assert!(
            first_only > 1000,
            "{first_only} rays behind the planes in slice 0 alone"
        );
    }

    /// Clipped rays sampling the slabs wholly behind the planes as without them
    /// (`EaVolume::clip_slabs`) give the frame of every slab cut slab by slab, to f32 rounding:
    /// a dense blob cut by one, two and three planes (faces across its middle, tilted to the
    /// slices), views from several sides and from inside the grid, `ea` and `combined`, the
    /// projections.
    #[test]
    fn slabs_behind_the_planes_are_sampled_as_without_them() {
        let vol = blob([40, 34, 30]);
        let data = vol.select(None).unwrap().data;
        let b = vol.bounds();
        let c = 0.5 * (b[0] + b[1]);
        let dense = dense_tf();
        let mut ev = EaVolume::new(&vol, &data, &dense).unwrap();
        let planes = test_planes(c);
        let (mut worst, mut shown) = (0.0f32, 0);
        for clip in planes {
            for cam in [
                Camera::orbit(b, 35.0, 25.0, 2.5, Some(40.0)),
                Camera::orbit(b, -120.0, -40.0, 3.0, None),
                inside_camera(b),
            ] {
                let mut view = EaView::new(&vol, cam, 37, 29, None, None, [1.0; 3]).unwrap();
                view.clip = clip.clone();
                let light = paper_light(1, 30.0);
                let frame = |ev: &EaVolume, i: usize| match i {
                    0 => ev.render_frame(&view, None).image,
                    1 => ev.render_frame(&view, Some(&light)).image,
                    _ => ev.render_projection(&view, Extremum::Max).image,
                };
                for i in 0..3 {
                    ev.clip_slabs = true;
                    let fast = frame(&ev, i);
                    ev.clip_slabs = false;
                    let cut = frame(&ev, i);
                    for (p, q) in fast.iter().zip(&cut) {
                        for k in 0..4 {
                            worst = worst.max((p[k] - q[k]).abs());
                        }
                    }
                    shown += fast.iter().filter(|p| p[3] > 0.5).count();
                }
            }
        }
        assert!(worst < 1e-4, "the frames differ by {worst}");
        assert!(shown > 500, "{shown} pixels show the volume");
    }

    #[test]
    fn projections_match_the_f64_twin() {
        use occlusion::projection::{extreme, shade};
        let vol = blob([40, 34, 30]);
        let data = vol.select(None).unwrap().data;
        let prepared = prepare(&data);
        let w2i = vol.affine.inverse();
        // A window whose low end leaves the margin's blocks empty, and one turned round
        // (transparent above): both sides of the empty-block rules, which must not change the
        // image (on a continuous field skipping where the rule ends the ray gives the same
        // image too: this does not tell the two apart; a test cannot, only their time does).
        let cam = Camera::orbit(vol.bounds(), 35.0, 25.0, 2.5, Some(40.0));
        for (t, clip) in [
            (window_ramp(0.2, 0.9), vec![]),
            (window_ramp(0.2, 0.9), vec![([1.0, 0.2, 0.0], 2.0)]),
            (window_ramp(0.3, 0.05), vec![]),
        ] {
            let ev = EaVolume::new(&vol, &data, &t).unwrap();
            assert!(ev.occupied.iter().any(|o| !o), "some blocks are empty");
            let mut v = EaView::new(&vol, cam, 40, 32, None, None, [0.1, 0.2, 0.3]).unwrap();
            v.clip = clip;
            for which in [Extremum::Max, Extremum::Min] {
                let img = ev.render_projection(&v, which).image;
                let (mut worst, mut shown) = (0.0f64, 0);
                for y in 0..32usize {
                    for x in 0..40usize {
                        let (o, d) = v.camera.ray(x as f64, y as f64, 40, 32);
                        let e = extreme(&prepared, vol.dims, &w2i, &v, o, d, which);
                        let c = shade(&t, e);
                        shown += (c[3] > 0.0) as usize;
                        let px = img[x + 40 * y];
                        for k in 0..3 {
                            let want = c[k] + (1.0 - c[3]) * v.background[k];
                            worst = worst.max((px[k] as f64 - want).abs());
                        }
                        worst = worst.max((px[3] as f64 - c[3]).abs());
                    }
                }
                // A ray's minimum is in the empty margin (transparent below a window), its
                // maximum in the blob (transparent above a turned-round one): the other two
                // show the volume.
                let below = t.points[0].2 == 0.0;
                if below == (which == Extremum::Max) {
                    assert!(shown > 50, "{which:?}: {shown} pixels show the volume");
                }
                assert!(
                    worst < 2e-3,
                    "{which:?}: CPU renderer and twin differ by {worst}"
                );
            }
        }
    }

    #[test]
    fn what_only_the_gpu_draws_is_refused() {
        let vol = blob([8, 8, 8]);
        let data = vol.select(None).unwrap().data;
        let mut t = tf();
        t.rows = vec![(0.0, 0), (1.0, 1)];
        assert!(EaVolume::new(&vol, &data, &t)
            .err()
            .unwrap()
            .contains("2-D"));
        assert!(EaVolume::new(&vol, &data[1..], &tf()).is_err());
    }
}
