//! Scene files (TOML): what `umbra render` draws and how. This module reads and checks
//! them; `umbra scene <file> [--set KEY=VALUE ...]` prints the resolved scene as JSON.
//!
//! Every key, its unit and default is documented in the README ("Scene files") and in the
//! commented example `datasets/scenes/example.toml`, which the tests parse. Unknown keys are
//! errors that name the key and its line; `--set section.key=value` overrides any key by its
//! dotted path (the value is read as a TOML value - `42`, `0.5`, `"text"`, `[1, 2, 3]` - and
//! as a string when it is none).
//!
//! Units: lengths in world units (mm for MRI data); extinction per world unit (a step of length
//! d has opacity `1 - exp(-sigma d)`, so images do not change with the slice count); angles in
//! degrees; colours as `[r, g, b]` in [0, 1] or `"#rrggbb"`.

pub use engine::method::{
    Combine, GeometryShadow, LineAoShading, Method, OcclusionModel, SurfaceAo,
};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A colour: `[r, g, b]` in [0, 1] or `"#rrggbb"`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Color {
    Rgb([f64; 3]),
    Hex(String),
}

impl Color {
    /// The colour as RGB in [0, 1], or why it is not one.
    pub fn rgb(&self) -> Result<[f64; 3], String> {
        match self {
            Color::Rgb(c) if c.iter().all(|v| (0.0..=1.0).contains(v)) => Ok(*c),
            Color::Rgb(c) => Err(format!("{c:?} has a component outside [0, 1]")),
            Color::Hex(s) => {
                let h = s.strip_prefix('#').unwrap_or("");
                if h.len() != 6 || !h.bytes().all(|b| b.is_ascii_hexdigit()) {
                    return Err(format!("'{s}' is not #rrggbb"));
                }
                // sRGB, as colour codes are everywhere (the PNG shows the code's colour);
                // the renderer works on linear values.
                let v = |i: usize| {
                    let c = u8::from_str_radix(&h[i..i + 2], 16).unwrap() as f64 / 255.0;
                    volume::colormap::srgb_to_linear(c)
                };
                Ok([v(0), v(2), v(4)])
            }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ProjectionKind {
    Perspective,
    Orthographic,
}

/// `[camera]`: either `eye`/`target`/`up`, or orbit angles around the scene's centre.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraSpec {
    pub projection: ProjectionKind,
    /// Vertical field of view, degrees (perspective).
    pub fov_y: f64,
    /// View height, world units (orthographic; default: fits the scene).
    pub height: Option<f64>,
    pub eye: Option<[f64; 3]>,
    /// Default: the centre of the scene's bounds.
    pub target: Option<[f64; 3]>,
    pub up: [f64; 3],
    /// Orbit angles (used when `eye` is absent), degrees.
    pub azimuth: f64,
    pub elevation: f64,
    /// Orbit distance in bounding-sphere radii.
    pub distance: f64,
    /// Clipping planes, world units (default: fitted to the scene's bounds).
    pub near: Option<f64>,
    pub far: Option<f64>,
}

impl Default for CameraSpec {
    fn default() -> Self {
        CameraSpec {
            projection: ProjectionKind::Perspective,
            fov_y: 35.0,
            height: None,
            eye: None,
            target: None,
            up: [0.0, 0.0, 1.0],
            azimuth: 30.0,
            elevation: 20.0,
            distance: 3.0,
            near: None,
            far: None,
        }
    }
}

/// One control point of a 1-D transfer function: value, colour, extinction per world unit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TfPoint {
    pub value: f64,
    pub color: Color,
    pub extinction: f64,
    /// Gradient magnitude at which this point applies (2-D transfer functions; all points of
    /// a 2-D function carry it).
    pub gradient: Option<f64>,
}

/// `[volume.transfer]`: a preset, or piecewise-linear points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TransferSpec {
    /// `grey`, `bone`, `fire`, `cool-warm` (ramps over the value range), or empty for `points`.
    pub preset: String,
    /// Extinction at the top of a preset's ramp, per world unit.
    pub extinction: f64,
    /// The values a preset's ramp spans.
    #[serde(skip_serializing_if = "TransferRange::is_full")]
    pub range: TransferRange,
    pub points: Vec<TfPoint>,
}

impl Default for TransferSpec {
    fn default() -> Self {
        TransferSpec {
            preset: "grey".into(),
            extinction: 0.5,
            range: TransferRange::default(),
            points: vec![],
        }
    }
}

impl TransferSpec {
    /// The transfer function given by `points` alone: a preset's keys (`preset`,
    /// `extinction`, `range`) at their defaults, as a scene with points must have them.
    pub fn from_points(points: Vec<TfPoint>) -> TransferSpec {
        TransferSpec {
            points,
            ..TransferSpec::default()
        }
    }
}

/// `volume.transfer.range`: `"full"` (the field's finite range), `"robust"` (its 2nd to 98th
/// percentiles) or `[lo, hi]` (values).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(
    untagged,
    expecting = "volume.transfer.range: \"full\", \"robust\" or [lo, hi]"
)]
pub enum TransferRange {
    Named(String),
    Values([f64; 2]),
}

impl Default for TransferRange {
    fn default() -> Self {
        TransferRange::Named("full".into())
    }
}

impl TransferRange {
    pub fn is_full(&self) -> bool {
        matches!(self, TransferRange::Named(n) if n == "full")
    }
}

/// A window (`volume.window`, `slices[].window`, `overlays[].range`): `[lo, hi]` (values),
/// `"full"` (the field's finite range) or `"robust"` (its 2nd to 98th percentiles).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Window {
    Named(String),
    Values([f64; 2]),
}

impl<'de> Deserialize<'de> for Window {
    /// A name or a list read first, its length checked after: an error about the list's
    /// length (or contents) is then reported at the key, not at the table that holds it.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged, expecting = "a window: \"full\", \"robust\" or [lo, hi]")]
        enum Raw {
            Named(String),
            Values(Vec<f64>),
        }
        match Raw::deserialize(d)? {
            Raw::Named(n) => Ok(Window::Named(n)),
            Raw::Values(v) if v.len() == 2 => Ok(Window::Values([v[0], v[1]])),
            Raw::Values(v) => Err(serde::de::Error::custom(format!(
                "a window: [lo, hi] holds two values, not {}",
                v.len()
            ))),
        }
    }
}

impl Window {
    /// The window's values: `full` for `"full"`, `robust()` (asked for only then) for
    /// `"robust"`, the values given otherwise (names are checked when the scene is read).
    pub fn resolve(&self, full: [f64; 2], robust: impl FnOnce() -> [f64; 2]) -> [f64; 2] {
        match self {
            Window::Values(v) => *v,
            Window::Named(n) if n == "robust" => robust(),
            Window::Named(_) => full,
        }
    }

    pub fn is_robust(&self) -> bool {
        matches!(self, Window::Named(n) if n == "robust")
    }
}

/// Which side of an isosurface is inside.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum IsoInside {
    Above,
    Below,
}

/// `[volume.iso]`: draw the volume as an isosurface with swept occlusion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IsoSpec {
    pub value: f64,
    #[serde(default = "default_inside")]
    pub inside: IsoInside,
    /// Distance field from `umbra sweep` (octants beside it); swept when absent.
    pub fields: Option<PathBuf>,
    #[serde(default = "default_iso_color")]
    pub color: Color,
    /// `uniform`, `overcast` or `octant:1..8`.
    #[serde(default = "default_sky")]
    pub sky: String,
    #[serde(default = "one")]
    pub gamma: f64,
    /// Flat-face correction c (visibilities looked up at P + c h_min N).
    #[serde(default = "default_offset")]
    pub offset: f64,
}

fn default_inside() -> IsoInside {
    IsoInside::Above
}
fn default_iso_color() -> Color {
    Color::Rgb([0.9, 0.9, 0.9])
}
fn default_sky() -> String {
    "uniform".into()
}
fn one() -> f64 {
    1.0
}
fn default_offset() -> f64 {
    volume::occlusion_shading::DEFAULT_OFFSET
}

/// `[volume]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VolumeSpec {
    pub path: PathBuf,
    /// Field: NAME, NAME:magnitude, NAME:x|y|z (default: the file's active array).
    pub field: Option<String>,
    #[serde(default)]
    pub transfer: TransferSpec,
    /// Isosurface mode: the volume drawn as this isosurface instead of by its transfer function.
    pub iso: Option<IsoSpec>,
    /// false: the volume is not drawn (its slices and overlays still use it and its grid).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub render: bool,
    /// The values the projections (`mip`, `minip`) and this volume's slices map through
    /// `colormap`: `[lo, hi]`, `"full"` (the field's finite range, the default) or `"robust"`
    /// (its 2nd to 98th percentiles).
    pub window: Option<Window>,
    /// The projections' and slices' colour map (default `grey`).
    pub colormap: Option<String>,
    /// The projections' opacity in [0, 1] (default 1).
    pub opacity: Option<f64>,
    /// true: a volume larger than the GPU passes' storage bindings hold is halved (2x2x2 box
    /// filter) until it fits, with a note; false (default): that is an error naming this key.
    #[serde(default, skip_serializing_if = "is_false")]
    pub downsample: bool,
}

fn is_false(b: &bool) -> bool {
    !*b
}

fn yes() -> bool {
    true
}
fn is_true(b: &bool) -> bool {
    *b
}

/// `[[slices]]`: a plane through the scene's volume or an overlay, drawn as a textured surface.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SliceSpec {
    /// `axial`, `coronal` or `sagittal`: normal to world z, y or x (RAS+).
    pub axis: Option<SliceAxis>,
    /// An oblique plane's normal (instead of `axis`; normalised).
    pub normal: Option<[f64; 3]>,
    /// World units along the unit normal (default: the centre of the volume's bounds).
    pub position: Option<f64>,
    /// The volume the slice shows: the scene's `[volume]` (default) or an overlay's `name`.
    pub volume: Option<String>,
    /// `[lo, hi]` mapped to the colour map's ends, `"full"` or `"robust"` (default:
    /// `volume.window`, else the field's finite range).
    pub window: Option<Window>,
    /// Default: `volume.colormap` for the scene's volume, else `grey`.
    pub colormap: Option<String>,
    #[serde(default = "one")]
    pub opacity: f64,
    /// Slab thickness, world units: tubes, lines and points are cropped to the slab
    /// `|n . p - position| <= slab / 2` (of any slice that has one).
    pub slab: Option<f64>,
    /// Draw the scene's overlays over the slice (default true).
    #[serde(default = "yes")]
    pub overlays: bool,
    /// Light the slice by the head light like the other surfaces (default false: its colours
    /// as mapped, darkened only by the method's occlusion terms).
    #[serde(default)]
    pub lit: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SliceAxis {
    Axial,
    Coronal,
    Sagittal,
}

/// `[[overlays]]`: a second volume resampled into the scene volume's grid, shown over slices.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OverlaySpec {
    /// The name slices use (`slices.volume`).
    pub name: String,
    pub path: PathBuf,
    pub field: Option<String>,
    /// Default `red-yellow` (scalars).
    pub colormap: Option<String>,
    /// `[lo, hi]`: values at or below `lo` are not shown, values above `hi` take the map's top; `lo >
    /// hi` turns it round (negative statistics); `"full"`: the field's finite range (the
    /// default); `"robust"`: the 2nd to 98th percentiles of its values in the volume's grid.
    pub range: Option<Window>,
    #[serde(default = "one")]
    pub opacity: f64,
    /// Row-major 4x4 from the overlay's world to the scene's.
    pub transform: Option<[f64; 16]>,
    /// A label volume: nearest-neighbour resampling, colours from `lut`.
    #[serde(default)]
    pub labels: bool,
    /// A FreeSurfer colour table (FreeSurferColorLUT.txt format); default: a colour per label.
    pub lut: Option<PathBuf>,
    /// The labels shown (default: every label in the table but 0).
    pub show: Option<Vec<i64>>,
    /// Blend the overlay into the volume rendering's colours too (at most one overlay).
    #[serde(default)]
    pub volume_blend: bool,
}

/// `[[tubes]]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TubesSpec {
    /// A tractogram (.trk, .tck, .vtk, .trx) or a mesh (.ply, .obj).
    pub path: PathBuf,
    #[serde(default = "default_radius")]
    pub radius: f64,
    /// `direction`, `scalar:NAME`, `volume:PATH`, or a colour.
    #[serde(default = "default_color")]
    pub color: String,
    /// The colour map of `scalar:NAME` / `volume:PATH` colours (default: the built-in ramp).
    pub colormap: Option<String>,
    /// Row-major 4x4 applied to the points.
    pub transform: Option<[f64; 16]>,
    /// Fitting tolerance, world units.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Sides of a ring (3 to 256), as `umbra tubes --sides`.
    #[serde(default = "default_sides")]
    pub sides: usize,
    /// In [0, 1]; below 1 the tubes are translucent (depth-peeled, `render.translucent_layers`).
    #[serde(default = "one")]
    pub opacity: f64,
    /// Only the streamlines these ROIs and ranges select (in the scene's world, after
    /// `transform`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub select: Option<SelectSpec>,
}

/// `select = { include_spheres = [[x, y, z, r]], ... }` of `[[tubes]]` and `[[lines]]`:
/// streamline selection (`tubes::select`; `umbra tracts select` takes the same as flags).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SelectSpec {
    /// Spheres `[x, y, z, r]` each of which a kept streamline has a point in.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub include_spheres: Vec<[f64; 4]>,
    /// Spheres no point of a kept streamline is in.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub exclude_spheres: Vec<[f64; 4]>,
    /// Boxes `[x0, y0, z0, x1, y1, z1]` (two opposite corners).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub include_boxes: Vec<[f64; 6]>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub exclude_boxes: Vec<[f64; 6]>,
    /// Volumes `FILE` (nonzero voxels) or `FILE:LABEL` (voxels equal to LABEL).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub include_masks: Vec<String>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub exclude_masks: Vec<String>,
    /// Arc length range, world units (inclusive).
    pub min_length: Option<f64>,
    pub max_length: Option<f64>,
    /// A per-streamline attribute (or a per-point one's mean) in `[attribute_min,
    /// attribute_max]` (each unbounded when absent).
    pub attribute: Option<String>,
    pub attribute_min: Option<f64>,
    pub attribute_max: Option<f64>,
    /// Keep this many of the streamlines that pass, at random.
    pub subsample: Option<usize>,
    /// The seed of `subsample`.
    #[serde(default)]
    pub seed: u64,
}

fn default_radius() -> f64 {
    0.5
}
fn default_color() -> String {
    "direction".into()
}
fn default_sides() -> usize {
    8
}

fn default_tolerance() -> f64 {
    0.05
}

/// How a line set's `width` is measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum WidthUnit {
    /// Pixels on screen, whatever the distance.
    #[default]
    Pixels,
    /// World units (lines thin with distance).
    World,
}

/// How a line is shaded across its width.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum LineProfile {
    /// One view-facing normal across the width (illuminated lines).
    #[default]
    Flat,
    /// A pseudo-tube: the normal turns and the depth bulges across the width.
    Cylinder,
}

/// `[[lines]]`: streamlines drawn as lines.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinesSpec {
    /// A tractogram (.trk, .tck, .vtk, .trx).
    pub path: PathBuf,
    /// `direction`, `scalar:NAME`, `volume:PATH`, or a colour.
    #[serde(default = "default_color")]
    pub color: String,
    /// The colour map of `scalar:NAME` / `volume:PATH` colours (default: the built-in ramp).
    pub colormap: Option<String>,
    /// Row-major 4x4 applied to the points.
    pub transform: Option<[f64; 16]>,
    /// The line's width, in `width_unit`.
    #[serde(default = "default_line_width")]
    pub width: f64,
    #[serde(default)]
    pub width_unit: WidthUnit,
    #[serde(default)]
    pub profile: LineProfile,
    /// The world radius the lines stand for where they shadow the volume (default: half the
    /// width for `width_unit = "world"`, 0 - no shadow - for pixel widths).
    pub proxy_radius: Option<f64>,
    /// A per-point time attribute, `scalar:NAME` (for `trail`).
    pub time: Option<String>,
    /// Draw only each line's tapered trail around a time.
    pub trail: Option<TrailSpec>,
    /// Depth-dependent halos (Everts et al. 2009).
    pub halo: Option<HaloSpec>,
    /// End tapers (Everts et al. §3.4).
    pub taper: Option<TaperSpec>,
    /// Draw only where an attribute (`scalar:NAME` or `volume:PATH`, sampled at the points)
    /// is at least `filter_min` (Everts et al. §3.6).
    pub filter: Option<String>,
    #[serde(default)]
    pub filter_min: f64,
    /// The attribute range over which the cut ends narrow to a point (0: square cuts).
    #[serde(default)]
    pub filter_taper: f64,
    /// Only the streamlines these ROIs and ranges select (see `[[tubes]] select`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub select: Option<SelectSpec>,
}

/// `[[points]]`: a point cloud drawn as discs facing the viewer (Everts et al. §3.5).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointsSpec {
    /// PLY vertices, CSV x,y,z, or a tractogram's points (`tubes::points`).
    pub path: PathBuf,
    /// `scalar:NAME`, `volume:PATH`, or a colour (default black).
    #[serde(default = "default_point_color")]
    pub color: String,
    /// The colour map of `scalar:NAME` / `volume:PATH` colours (default: the built-in ramp).
    pub colormap: Option<String>,
    /// Row-major 4x4 applied to the points.
    pub transform: Option<[f64; 16]>,
    /// The disc's diameter in world units.
    #[serde(default = "default_point_size")]
    pub size: f64,
    /// Halos as on lines; `width` is the halo disc's diameter over the point's.
    pub halo: Option<HaloSpec>,
}

fn default_point_color() -> String {
    "#000000".into()
}
fn default_point_size() -> f64 {
    1.0
}

/// `[[lines]] taper = { vertices = 2, u = 0.2 }`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TaperSpec {
    /// The end vertices the taper spans.
    pub vertices: u32,
    /// Their share of the line's parameter u at each end.
    pub u: f64,
}

impl Default for TaperSpec {
    fn default() -> Self {
        TaperSpec {
            vertices: 2,
            u: 0.2,
        }
    }
}

/// `[[lines]] halo = { mode, style, width, d_max, displacement, depth_cue }`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HaloSpec {
    /// `none`, `uniform` (no displacement: every line its full rim) or `depth`.
    pub mode: HaloMode,
    /// `gap` (rims hide what is behind them and are no surface) or `outline` (dark rims that
    /// belong to the line).
    pub style: HaloStyle,
    /// The strip's width over the line's (w_strip / w_line).
    pub width: f64,
    /// The rim's push back at the strip's edge, a fraction of the camera's near..far range.
    pub d_max: f64,
    /// `linear`, `sqrt` or `square`: eq. 3's f.
    pub displacement: HaloDisplacement,
    /// The core narrows to `1 - depth_cue` of its width at the far plane (0: off).
    pub depth_cue: f64,
}

impl Default for HaloSpec {
    fn default() -> Self {
        HaloSpec {
            mode: HaloMode::Depth,
            style: HaloStyle::Gap,
            width: 6.0,
            d_max: 0.01,
            displacement: HaloDisplacement::Linear,
            depth_cue: 0.0,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum HaloMode {
    None,
    Uniform,
    #[default]
    Depth,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum HaloStyle {
    #[default]
    Gap,
    Outline,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum HaloDisplacement {
    #[default]
    Linear,
    Sqrt,
    Square,
}

impl HaloSpec {
    /// The line set's halo (`None` for `mode = "none"`).
    pub fn halo(&self) -> Option<tubes::lines::Halo> {
        use tubes::lines::{Displacement, Halo};
        (self.mode != HaloMode::None).then(|| Halo {
            uniform: self.mode == HaloMode::Uniform,
            outline: self.style == HaloStyle::Outline,
            width: self.width as f32,
            d_max: self.d_max as f32,
            displacement: match self.displacement {
                HaloDisplacement::Linear => Displacement::Linear,
                HaloDisplacement::Sqrt => Displacement::Sqrt,
                HaloDisplacement::Square => Displacement::Square,
            },
            depth_cue: self.depth_cue as f32,
        })
    }
}

/// `[render.illustrative]`: the colours of the illustrative method.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IllustrativeSpec {
    pub line: Color,
    pub halo: Color,
}

impl Default for IllustrativeSpec {
    fn default() -> Self {
        IllustrativeSpec {
            line: Color::Rgb([0.0; 3]),
            halo: Color::Rgb([1.0; 3]),
        }
    }
}

/// `[[lines]] trail = { now, back, forward, start, min_width }` (Köhler et al. 2011, §4.1), in
/// the time attribute's units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrailSpec {
    /// The particle's time.
    pub now: f64,
    /// How far back and forward in time the trail reaches.
    pub back: f64,
    pub forward: f64,
    /// The fraction of the way to either end where the width starts to fall.
    #[serde(default = "default_trail_start")]
    pub start: f64,
    /// The width at the trail's ends, as a fraction of `width`.
    #[serde(default = "default_trail_min_width")]
    pub min_width: f64,
}

fn default_trail_start() -> f64 {
    1.0 / 3.0
}

fn default_trail_min_width() -> f64 {
    0.25
}

impl LinesSpec {
    /// `proxy_radius` with its default.
    pub fn proxy_radius(&self) -> f64 {
        self.proxy_radius.unwrap_or(match self.width_unit {
            WidthUnit::World => 0.5 * self.width,
            WidthUnit::Pixels => 0.0,
        })
    }
}

/// `[render.lineao]`: LineAO's parameters (Eichelbaum et al. 2013, §3.2.3; the model and its
/// departures from the paper: `occlusion::line_ao`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LineAoSpec {
    /// `s_h`: samples of the first disc; level j takes `ceil(s_h / (j + 1))`.
    pub samples: u32,
    /// `s_r`: discs and pyramid levels, 1 to 8.
    pub levels: u32,
    /// `r0` in line widths (lines: their width on screen; tubes: `z(P)` times the diameter).
    pub r0: f64,
    /// Radius added per level, world units (projected by `z(P)`).
    pub radius_step: f64,
    /// `delta_0`: the least normalised depth difference that occludes.
    pub delta0: f64,
    /// `paper` (eq. 11) or `constant`.
    pub falloff: Falloff,
    /// `plane` (a sample occludes above P's tangent plane) or `height` (the paper's eq. 8).
    pub visibility: AoVisibility,
    /// `sum` (eq. 7) or `mean` (OpenWalnut) of the levels' occlusion.
    pub levels_combine: AoLevels,
    /// `I_s`, the head light's intensity in `g_light` (eq. 14); 0 turns `g_light` off.
    pub light_intensity: f64,
    /// Anisotropic LineAO (Köhler et al. eq. 10-12): lines running alongside P occlude less.
    pub anisotropic: bool,
    /// `invariant` (doubled-angle tangents) or `paper` (`|t.x|`, eq. 10).
    pub alignment: AoAlignment,
    /// `I` of eq. 11.
    pub intensity: f64,
    /// `A0` of eq. 11, the least alignment factor.
    pub floor: f64,
    /// The guard band's cap in pixels (0: no band).
    pub guard: u32,
    /// `phong` (umbra's head light times the AO) or `paper` (colour times the AO).
    pub shading: LineAoShading,
    /// Seed of the per-pixel rotation of the samples.
    pub seed: u32,
}

/// `render.lineao.falloff`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Falloff {
    #[default]
    Paper,
    Constant,
}

/// `render.lineao.alignment`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum AoAlignment {
    #[default]
    Invariant,
    Paper,
}

/// `render.lineao.levels_combine`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum AoLevels {
    #[default]
    Sum,
    Mean,
}

/// `render.lineao.visibility`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum AoVisibility {
    #[default]
    Plane,
    Height,
}

impl Default for LineAoSpec {
    fn default() -> Self {
        LineAoSpec {
            samples: 32,
            levels: 3,
            r0: 1.5,
            radius_step: 1.0,
            delta0: 1e-4,
            falloff: Falloff::Paper,
            visibility: AoVisibility::Plane,
            levels_combine: AoLevels::Sum,
            light_intensity: 0.5,
            anisotropic: false,
            alignment: AoAlignment::Invariant,
            intensity: 15.0,
            floor: 0.1,
            guard: 64,
            shading: LineAoShading::Phong,
            seed: 0,
        }
    }
}

impl LineAoSpec {
    /// The engine's settings, with the head light's material `light` (ambient, diffuse,
    /// specular, shininess) for the BRDF of `g_light`.
    pub fn settings(&self, light: [f64; 4]) -> engine::method::LineAo {
        use occlusion::line_ao as la;
        engine::method::LineAo {
            kernel: la::LineAoSettings {
                levels: self.levels,
                samples: self.samples,
                r0_widths: self.r0 as f32,
                line_width: la::LineWidth::Pixels(2.0),
                radius_step: self.radius_step as f32,
                delta0: self.delta0 as f32,
                light_intensity: self.light_intensity as f32,
                light_diffuse: light[1] as f32,
                light_specular: light[2] as f32,
                light_shininess: light[3] as f32,
                seed: self.seed,
                falloff: match self.falloff {
                    Falloff::Paper => la::Falloff::Paper,
                    Falloff::Constant => la::Falloff::Constant,
                },
                visibility: match self.visibility {
                    AoVisibility::Plane => la::Visibility::Plane,
                    AoVisibility::Height => la::Visibility::Height,
                },
                levels_combine: match self.levels_combine {
                    AoLevels::Sum => la::LevelsCombine::Sum,
                    AoLevels::Mean => la::LevelsCombine::Mean,
                },
                anisotropic: self.anisotropic,
                alignment: match self.alignment {
                    AoAlignment::Invariant => la::Alignment::Invariant,
                    AoAlignment::Paper => la::Alignment::Paper,
                },
                intensity: self.intensity as f32,
                floor: self.floor as f32,
                // Camera quantities: the pass takes them from the camera.
                depth_range: 1.0,
                ray_focal: 0.0,
            },
            guard: self.guard,
            shading: self.shading,
        }
    }
}

fn default_line_width() -> f64 {
    2.0
}

/// `[[clip]]`: keeps the half-space `normal . x <= offset`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipSpec {
    pub normal: [f64; 3],
    pub offset: f64,
    /// Cut the volume only, leaving the tubes whole (the paper's Fig. 11).
    #[serde(default)]
    pub volume_only: bool,
}

/// `[light]`: a head light with Phong parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LightSpec {
    pub ambient: f64,
    pub diffuse: f64,
    pub specular: f64,
    pub shininess: f64,
}

impl Default for LightSpec {
    fn default() -> Self {
        LightSpec {
            ambient: 0.3,
            diffuse: 0.7,
            specular: 0.3,
            shininess: 32.0,
        }
    }
}

/// Default vicinity depth bias as a fraction of `vicinity_distance`.
pub const VICINITY_BIAS: f64 = 0.05;

/// `[render]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderSpec {
    pub method: Method,
    pub width: u32,
    pub height: u32,
    /// Slice count (default: chosen from the data) or distance between slices (world units).
    pub slices: Option<u32>,
    pub slice_distance: Option<f64>,
    /// Occlusion cone half-angle, degrees.
    pub theta: f64,
    /// Occlusion blur samples per axis (n x n).
    pub blur_samples: u32,
    /// Vicinity samples (Poisson disk, at most 118).
    pub vicinity_samples: u32,
    /// Virtual slice distance l_vicinity, world units.
    pub vicinity_distance: f64,
    /// Vicinity depth bias, world units (default: 5% of `vicinity_distance`).
    pub vicinity_bias: Option<f64>,
    /// Extinction of the tubes for light travelling through the volume, per world unit.
    pub geometry_extinction: f64,
    /// `inside` (the tubes' thickness) or `column` (the paper's endless shadow).
    pub geometry_shadow: GeometryShadow,
    pub combine: Combine,
    /// Edge of the occlusion buffer's cells in pixels, 1 to 16 (default: 2, or larger when
    /// the light volume would not fit the adapter).
    pub occlusion_cell: Option<u32>,
    /// Eye slices per step of the light volume: 1, 2, 4 or 8 (default: as many as fit in the
    /// smallest voxel spacing where the volume alone casts the light, else 1).
    pub occlusion_step: Option<u32>,
    /// `paper` (constant blur per slice) or `cone` (follows the cone; slice-count independent).
    pub occlusion_model: OcclusionModel,
    /// MSAA samples (lowered to what the adapter supports, with a warning).
    pub msaa: u32,
    pub fxaa: bool,
    /// What fills a method's surface-AO slot: `vicinity` (Schott et al.), `lineao`
    /// (Eichelbaum et al.) or `none`.
    pub surface_ao: SurfaceAo,
    pub lineao: LineAoSpec,
    pub illustrative: IllustrativeSpec,
    /// Bits per channel of a PNG: 8, or 1 (two values only, for print).
    pub bits: u32,
    /// `none` or `anaglyph` (red = left eye; Everts et al. §3.7).
    pub stereo: Stereo,
    /// `auto`, `gpu` or `cpu`: who draws the frame (the native CPU renderer draws `ea`
    /// volumes; `auto` picks it on a CPU adapter where it can).
    pub device: Device,
    /// Translucent layers peeled per pixel (1 to 8): translucent tubes and slices beyond
    /// this many on a ray are not drawn.
    pub translucent_layers: u32,
    /// World units between the eyes (default: `convergence / 30`).
    pub eye_separation: Option<f64>,
    /// View distance of the plane with no disparity, world units (default: the distance from
    /// the eye to the camera's target).
    pub convergence: Option<f64>,
}

/// `render.device`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    #[default]
    Auto,
    Gpu,
    Cpu,
}

/// `render.stereo`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Stereo {
    #[default]
    None,
    Anaglyph,
}

impl Default for RenderSpec {
    fn default() -> Self {
        RenderSpec {
            method: Method::Combined,
            width: 1024,
            height: 768,
            slices: None,
            slice_distance: None,
            theta: 25.0,
            blur_samples: 3,
            vicinity_samples: 32,
            vicinity_distance: 2.0,
            vicinity_bias: None,
            geometry_extinction: 10.0,
            geometry_shadow: GeometryShadow::Inside,
            combine: Combine::Min,
            occlusion_cell: None,
            occlusion_step: None,
            occlusion_model: OcclusionModel::Paper,
            msaa: 4,
            fxaa: true,
            surface_ao: SurfaceAo::Vicinity,
            lineao: LineAoSpec::default(),
            illustrative: IllustrativeSpec::default(),
            bits: 8,
            stereo: Stereo::None,
            device: Device::Auto,
            translucent_layers: 4,
            eye_separation: None,
            convergence: None,
        }
    }
}

/// What the ground truth of `[render]` depends on: the light model a method approximates.
/// With the image size, the camera, the light, the background and the data, it determines the
/// Monte Carlo reference ([`Scene::reference_key`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LightModel {
    pub width: u32,
    pub height: u32,
    pub theta: f64,
    pub geometry_extinction: f64,
    pub geometry_shadow: GeometryShadow,
    pub vicinity_distance: f64,
    pub stereo: Stereo,
    pub eye_separation: Option<f64>,
    pub convergence: Option<f64>,
}

/// How a method approximates the light model: what a method may change without changing the
/// reference image.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Approximation {
    pub method: Method,
    pub slices: Option<u32>,
    pub slice_distance: Option<f64>,
    pub blur_samples: u32,
    pub vicinity_samples: u32,
    pub vicinity_bias: Option<f64>,
    pub combine: Combine,
    pub occlusion_cell: Option<u32>,
    pub occlusion_step: Option<u32>,
    pub occlusion_model: OcclusionModel,
    pub msaa: u32,
    pub fxaa: bool,
    pub surface_ao: SurfaceAo,
    pub lineao: LineAoSpec,
    pub illustrative: IllustrativeSpec,
    pub bits: u32,
    pub device: Device,
    pub translucent_layers: u32,
}

impl RenderSpec {
    /// The keys of `[render]` split into the light model and its approximation. The
    /// destructuring names every field, so a new key does not compile until it is put on one
    /// side: the reference cache has no list of keys to keep up to date.
    pub fn split(&self) -> (LightModel, Approximation) {
        let RenderSpec {
            method,
            width,
            height,
            slices,
            slice_distance,
            theta,
            blur_samples,
            vicinity_samples,
            vicinity_distance,
            vicinity_bias,
            geometry_extinction,
            geometry_shadow,
            combine,
            occlusion_cell,
            occlusion_step,
            occlusion_model,
            msaa,
            fxaa,
            surface_ao,
            lineao,
            illustrative,
            bits,
            stereo,
            device,
            translucent_layers,
            eye_separation,
            convergence,
        } = self.clone();
        (
            LightModel {
                width,
                height,
                theta,
                geometry_extinction,
                geometry_shadow,
                vicinity_distance,
                stereo,
                eye_separation,
                convergence,
            },
            Approximation {
                method,
                slices,
                slice_distance,
                blur_samples,
                vicinity_samples,
                vicinity_bias,
                combine,
                occlusion_cell,
                occlusion_step,
                occlusion_model,
                msaa,
                fxaa,
                surface_ao,
                lineao,
                illustrative,
                bits,
                device,
                translucent_layers,
            },
        )
    }
}

/// What a Monte Carlo reference image depends on: the whole scene but for how a method
/// approximates it (see [`RenderSpec::split`]); serialised and hashed for the cache.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReferenceKey<'a> {
    pub camera: &'a CameraSpec,
    pub background: &'a Color,
    pub volume: &'a Option<VolumeSpec>,
    pub tubes: &'a [TubesSpec],
    pub lines: &'a [LinesSpec],
    pub points: &'a [PointsSpec],
    pub slices: &'a [SliceSpec],
    pub overlays: &'a [OverlaySpec],
    pub clip: &'a [ClipSpec],
    pub light: &'a LightSpec,
    pub model: LightModel,
}

/// A scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    #[serde(default)]
    pub camera: CameraSpec,
    #[serde(default = "default_background")]
    pub background: Color,
    pub volume: Option<VolumeSpec>,
    #[serde(default)]
    pub tubes: Vec<TubesSpec>,
    #[serde(default)]
    pub lines: Vec<LinesSpec>,
    #[serde(default)]
    pub points: Vec<PointsSpec>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub slices: Vec<SliceSpec>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub overlays: Vec<OverlaySpec>,
    #[serde(default)]
    pub clip: Vec<ClipSpec>,
    #[serde(default)]
    pub light: LightSpec,
    #[serde(default)]
    pub render: RenderSpec,
    /// Text and marks drawn over the image (`crate::annotate`).
    #[serde(default, skip_serializing_if = "AnnotateSpec::is_empty")]
    pub annotate: AnnotateSpec,
}

/// `[annotate]`: a title, orientation labels, a scale bar and a colour bar over the image.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnnotateSpec {
    /// Text at the top centre.
    pub title: Option<String>,
    /// L/R, A/P, S/I at the middle of each edge: the anatomical direction that points there.
    #[serde(default)]
    pub orientation: bool,
    /// A scale bar at the bottom left: its length in world units, or `"auto"` (1, 2 or 5 times
    /// a power of ten, about a fifth of the image width).
    pub scale_bar: Option<ScaleBarSpec>,
    /// Units written after the scale bar's length (default `mm` for RAS+ data, else `units`).
    pub units: Option<String>,
    /// A colour bar at the bottom right of the colouring of `volume` (its transfer
    /// function), `tubes.N` or `lines.N` (their `scalar:NAME` or `volume:PATH` colours).
    pub colorbar: Option<String>,
    /// The colour bar's label (default: the attribute's or field's name).
    pub colorbar_label: Option<String>,
    /// Units written after the colour bar's label, in brackets.
    pub colorbar_units: Option<String>,
    /// Colour of text and marks (default black on light backgrounds, white on dark ones).
    pub color: Option<Color>,
}

impl AnnotateSpec {
    pub fn is_empty(&self) -> bool {
        *self == AnnotateSpec::default()
    }
}

/// `annotate.scale_bar`: a length or `"auto"`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ScaleBarSpec {
    Length(f64),
    Word(String),
}

impl Scene {
    /// The parts of the scene its ground truth depends on.
    pub fn reference_key(&self) -> ReferenceKey<'_> {
        let Scene {
            camera,
            background,
            volume,
            tubes,
            lines,
            points,
            slices,
            overlays,
            clip,
            light,
            render,
            annotate: _,
        } = self;
        ReferenceKey {
            camera,
            background,
            volume,
            tubes,
            lines,
            points,
            slices,
            overlays,
            clip,
            light,
            model: render.split().0,
        }
    }
}

/// Checks a tube or line set's colour source: `direction`, `scalar:NAME`, `volume:PATH` or
/// `#rrggbb`.
fn check_color_source(c: &str) -> Result<(), String> {
    let ok = c == "direction"
        || c.starts_with("scalar:")
        || c.starts_with("volume:")
        || Color::Hex(c.to_string()).rgb().is_ok();
    if ok {
        Ok(())
    } else {
        Err(format!(
            "'{c}' is not direction, scalar:NAME, volume:PATH or #rrggbb"
        ))
    }
}

fn default_background() -> Color {
    Color::Rgb([1.0, 1.0, 1.0])
}

/// Sets `dotted.key = value` in a TOML table (creating tables on the way).
fn set(table: &mut toml::Table, key: &str, value: &str) -> Result<(), String> {
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(format!("override {key}: empty key component"));
    }
    // The value as TOML, else as a string.
    let v: toml::Value = format!("v = {value}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_string()));
    let mut t = table;
    for (i, p) in parts.iter().enumerate() {
        if i + 1 == parts.len() {
            t.insert(p.to_string(), v);
            return Ok(());
        }
        if let Some(n) = parts.get(i + 1).and_then(|s| s.parse::<i64>().ok()) {
            if n < 0 {
                return Err(format!(
                    "override {key}: index {n} of '{p}'; entries count from 0"
                ));
            }
        }
        // `tubes.0.radius`: an index into an array of tables - one the scene has (an index
        // makes no table of its own: `tubes.0` with no `[[tubes]]` is not a first entry).
        if !t.contains_key(*p) && parts.get(i + 1).is_some_and(|s| s.parse::<usize>().is_ok()) {
            let path = parts[..=i].join(".");
            // The lists of tables (`[[tubes]]`, `volume.transfer.points`); other lists hold
            // values (`background`, `camera.eye`).
            let tables = match i {
                0 => ["tubes", "lines", "points", "slices", "overlays", "clip"].contains(p),
                _ => path == "volume.transfer.points",
            };
            return Err(match tables {
                true => format!(
                    "override {key}: the scene has no '{path}' entries to index; add them to the \
                     file (e.g. [[{path}]]) and set their keys there or with {path}.N.KEY"
                ),
                false => format!(
                    "override {key}: the scene file does not hold '{path}', so there is no entry \
                     to set; give the whole value ({path}=[...])"
                ),
            });
        }
        let entry = t
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        t = match entry {
            toml::Value::Table(tt) => tt,
            toml::Value::Array(a) => {
                let n = a.len();
                let idx: usize =
                    parts
                        .get(i + 1)
                        .and_then(|s| s.parse().ok())
                        .ok_or_else(|| {
                            format!(
                        "override {key}: '{p}' is a list; give an index from 0 to {} after it",
                        n.saturating_sub(1)
                    )
                        })?;
                // The index is consumed here: continue from the element with the rest.
                let rest = parts[i + 2..].join(".");
                let el = a
                    .get_mut(idx)
                    .ok_or_else(|| format!("override {key}: '{p}' has {n} entries"))?;
                return match el {
                    toml::Value::Table(tt) if !rest.is_empty() => set(tt, &rest, value),
                    toml::Value::Table(_) => Err(format!(
                        "override {key}: an entry of '{p}' is not replaced whole; set its keys \
                         ({p}.{idx}.KEY=VALUE)"
                    )),
                    // One value of a list of values (`background.0=1.0`).
                    el if rest.is_empty() => {
                        *el = v;
                        Ok(())
                    }
                    _ => Err(format!(
                        "override {key}: '{p}' holds values, not tables: nothing inside '{p}.{idx}' \
                         to set"
                    )),
                };
            }
            _ => return Err(format!("override {key}: '{p}' is not a table")),
        };
    }
    Ok(())
}

/// Which of `overrides` (`(key, value, label)` in the order they applied, keys dotted as
/// `slices.0.position`, values as given) gave the value an error is about: the error names a
/// scene key ("scene key slices[0].position", or a message or part of one that begins with the
/// key, "volume.iso.value: ..."; `[N]` read as `.N`) that is the override's key or lies in the
/// table it set; or, for a data file's path (a key `path` or `*.path`), the error quotes the
/// path given (a file that cannot be read is named by its path, not its key). Of several
/// overrides of the key the last, which applied last, is the one; `None` where the error names
/// no key or path the overrides set.
pub fn blamed_override<'a>(
    err: &str,
    overrides: &'a [(String, String, String)],
) -> Option<&'a str> {
    if overrides.is_empty() {
        return None;
    }
    // Where a key may start: after "scene key ", at the start, or after ": ".
    let mut starts: Vec<usize> = err
        .match_indices("scene key ")
        .map(|(i, m)| i + m.len())
        .collect();
    starts.push(0);
    starts.extend(err.match_indices(": ").map(|(i, m)| i + m.len()));
    for at in starts {
        let rest = &err[at..];
        let key: String = rest
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '[' | ']'))
            .collect();
        // A bare key must end at a colon or a space (not a file name's dot-separated parts).
        let after = rest[key.len()..].chars().next();
        if key.is_empty() || !matches!(after, Some(':') | Some(' ') | None) {
            continue;
        }
        let dotted = key.replace('[', ".").replace(']', "");
        let dotted = dotted.trim_end_matches('.');
        if let Some((_, _, label)) = overrides
            .iter()
            .rev()
            .find(|(k, _, _)| dotted == k || dotted.starts_with(&format!("{k}.")))
        {
            return Some(label);
        }
    }
    overrides
        .iter()
        .rev()
        .find(|(k, v, _)| {
            let v = v.trim().trim_matches(|c| c == '"' || c == '\'');
            (k == "path" || k.ends_with(".path")) && !v.is_empty() && quotes_path(err, v)
        })
        .map(|(_, _, label)| label.as_str())
}

/// Whether `err` names the file `path` (as given, or resolved against a folder): `path` whole,
/// after the start, a blank, `(` or a `/`, and before the end, a blank, `:` or `)` (`fa.nii`
/// is not named by an error about `/data/sub-01/fa.nii.gz`, nor `a.nii` by one about `fa.nii`).
fn quotes_path(err: &str, path: &str) -> bool {
    err.match_indices(path).any(|(i, _)| {
        let before = err[..i].chars().next_back();
        let after = err[i + path.len()..].chars().next();
        matches!(before, None | Some(' ' | '(' | '/'))
            && matches!(after, None | Some(' ' | ':' | ')'))
    })
}

/// What an error says where [`blamed_override`] finds the override that gave the value (its
/// `label`): "(the value comes from LABEL, not from the scene file)".
pub const BLAME_PREFIX: &str = "(the value comes from ";

/// Reads a scene from TOML text; `name` labels errors, relative paths resolve against `dir`.
pub fn parse(text: &str, name: &str, dir: &Path, overrides: &[String]) -> Result<Scene, String> {
    // Parse as written first: serde's errors then carry the line of an unknown or bad key.
    // The parser quotes the line (and marks it): each line of its message is cut to 1000
    // characters, so that a 5 MB value gives a short error.
    let short = |e: &dyn std::fmt::Display| {
        let text = e.to_string();
        // (As the CLI cuts what it prints; long enough for the list of a table's keys after an
        // unknown one, which 400 cut mid-word.)
        let lines: Vec<String> = text
            .lines()
            .map(|l| volume::clip_text(&plain(l), 1000))
            .collect();
        let mut out = format!("{name}: {}", lines.join("\n"));
        if text.contains("missing field `path`") {
            out += " (every [volume], [[tubes]], [[lines]], [[points]] and [[overlays]] entry \
                    names its data file with path; the marked line is the entry's)";
        }
        out
    };
    let mut scene: Scene = toml::from_str(text).map_err(|e| short(&e))?;
    if !overrides.is_empty() {
        let mut table: toml::Table = text.parse().map_err(|e| short(&e))?;
        for o in overrides {
            let (k, v) = o
                .split_once('=')
                .ok_or_else(|| format!("override {o}: expected KEY=VALUE"))?;
            if let Some(at) = k.find('[') {
                let (head, rest) = k.split_at(at);
                let index = rest
                    .trim_start_matches('[')
                    .split(']')
                    .next()
                    .unwrap_or("0");
                return Err(format!(
                    "override {k}: an entry of an array is named by a dot and its index \
                     ({head}.{index}{}), not by brackets",
                    rest.split_once(']').map(|(_, r)| r).unwrap_or("")
                ));
            }
            set(&mut table, k.trim(), v.trim())?;
        }
        // Through TOML text, so that an error has a place: the key and, in an array of
        // tables, the entry (`volume.transfer.points[1].extinction`).
        let merged = toml::to_string(&table).map_err(|e| format!("{name} with overrides: {e}"))?;
        scene = toml::from_str(&merged)
            .map_err(|e| format!("{name} with overrides: {}", merged_error(&merged, &e)))?;
    }
    validate(&mut scene, dir).map_err(|e| format!("{name}: {e}"))?;
    Ok(scene)
}

/// An error of the scene merged with its overrides (`merged`, as `toml::to_string` writes
/// it: a header per table, `[[...]]` per entry of an array of tables, a key a line) as the
/// key's dotted path, with the entry's index in an array of tables, and the message.
fn merged_error(merged: &str, e: &toml::de::Error) -> String {
    let Some(span) = e.span() else {
        return e.message().to_string();
    };
    let start = span.start.min(merged.len());
    // An error of a whole table (a missing field) spans it from its header: the header's line
    // counts as the table's own, with no key.
    // (An array value's `[` after its key is not a header: only one that begins its line.)
    let line_start = merged[..start].rfind('\n').map_or(0, |i| i + 1);
    let header = merged[start..].starts_with('[') && merged[line_start..start].trim().is_empty();
    let end = if header {
        start + merged[start..].find('\n').unwrap_or(merged.len() - start)
    } else {
        start
    };
    let before = &merged[..end];
    let line = before.rsplit('\n').next().unwrap_or("");
    let key = if header {
        ""
    } else {
        line.split('=').next().unwrap_or("").trim()
    };
    // The table the key is in: the last header above it, and for an array of tables how many
    // of the same header came before (the entry's index).
    let mut path = String::new();
    let mut seen: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
    for l in before.lines().map(str::trim) {
        if let Some(h) = l.strip_prefix("[[").and_then(|h| h.strip_suffix("]]")) {
            let n = seen.entry(h).or_insert(0);
            path = format!("{h}[{n}]");
            *n += 1;
        } else if let Some(h) = l.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
            // A table inside an entry of an array of tables (`[lines.halo]` after `[[lines]]`):
            // the entry's index too (`lines[0].halo`), from the longest such array above.
            path = seen
                .iter()
                .filter(|(a, _)| h.strip_prefix(**a).is_some_and(|r| r.starts_with('.')))
                .max_by_key(|(a, _)| a.len())
                .map(|(a, n)| format!("{a}[{}]{}", n - 1, &h[a.len()..]))
                .unwrap_or_else(|| h.to_string());
        }
    }
    let mut full = match (path.is_empty(), key.is_empty()) {
        (_, true) => path,
        (true, false) => key.to_string(),
        (false, false) => format!("{path}.{key}"),
    };
    // An unknown field's error names the field; where the line found is not that field's
    // (an unknown top-level table from `--set foo.bar=1` is reported at another table's
    // position: "clip[0].[: unknown field `foo`"), the message alone.
    if let Some(field) = e
        .message()
        .strip_prefix("unknown field `")
        .and_then(|r| r.split('`').next())
    {
        // (A table's own position, no key on its line, names the table the field is in:
        // the key is the field in it, `volume.bogus`.)
        if !key.is_empty() && key != field {
            full = String::new();
        } else if key.is_empty() && !full.is_empty() {
            full = format!("{full}.{field}");
        }
    }
    // A key at the top level (`--set foo=1`) has no table to name: the message alone (it
    // read ": unknown field `foo`").
    let message = plain(e.message().trim());
    if full.is_empty() {
        return message;
    }
    format!("{full}: {message}")
}

/// A deserializer's message in the scene's words: a fraction where a whole number belongs
/// ("invalid type: floating point `2.5`, expected i64") says so.
fn plain(message: &str) -> String {
    let whole = ["i64", "u64", "u32", "usize", "i32", "u16", "u8"];
    if let Some(rest) = message.strip_prefix("invalid type: floating point `") {
        if let Some((value, expected)) = rest.split_once("`, expected ") {
            if whole.contains(&expected.trim()) {
                return format!("{value} is not a whole number (a whole number is expected here)");
            }
        }
    }
    message.to_string()
}

/// Reads a scene file.
pub fn load(path: &Path, overrides: &[String]) -> Result<Scene, String> {
    let data = data_kind(path).map(|kind| {
        format!(
            "{}: a {kind} file, not a scene: a scene is a TOML file that names it (for example \
             `[volume]` with `path = \"...\"`, `[[lines]]` or `[[tubes]]` with theirs)",
            path.display()
        )
    });
    let text = volume::read_text(path, 16 << 20).map_err(|e| {
        data.clone()
            .unwrap_or_else(|| format!("{}: {e}", path.display()))
    })?;
    let dir = path.parent().unwrap_or(Path::new("."));
    parse(&text, &path.display().to_string(), dir, overrides).map_err(|e| data.unwrap_or(e))
}

/// What a file named like data, not a scene, holds by its name: "volume", "tractogram" or
/// "mesh" (`.toml` and other names: none).
fn data_kind(path: &Path) -> Option<&'static str> {
    let name = path.file_name()?.to_str()?.to_ascii_lowercase();
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    let ext = name.rsplit_once('.')?.1;
    match ext {
        "nii" | "nrrd" | "nhdr" | "vti" | "mhd" | "mha" | "slc" | "hdr" | "img" => Some("volume"),
        "trk" | "tck" | "trx" => Some("tractogram"),
        "ply" | "obj" => Some("mesh"),
        _ => None,
    }
}

/// The scene as a TOML file that [`load`] reads back to the same scene wherever the file is
/// saved: every data path made absolute (relative paths were resolved against the scene's
/// folder when it was loaded, so they are relative to the working directory here).
pub fn to_toml(s: &Scene) -> Result<String, String> {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let abs_source = |c: &mut String| {
        if let Some(p) = c.strip_prefix("volume:") {
            *c = format!("volume:{}", abs(Path::new(p)).display());
        }
    };
    let mut s = s.clone();
    if let Some(v) = &mut s.volume {
        v.path = abs(&v.path);
        if let Some(f) = v.iso.as_mut().and_then(|i| i.fields.as_mut()) {
            *f = abs(f);
        }
    }
    let abs_masks = |sel: &mut Option<SelectSpec>| {
        for m in sel
            .iter_mut()
            .flat_map(|s| s.include_masks.iter_mut().chain(s.exclude_masks.iter_mut()))
        {
            if let Ok((p, _)) = tubes::select::split_mask(m) {
                let a = abs(Path::new(p)).display().to_string();
                *m = format!("{a}{}", &m[p.len()..]);
            }
        }
    };
    for t in &mut s.tubes {
        t.path = abs(&t.path);
        abs_source(&mut t.color);
        abs_masks(&mut t.select);
    }
    for l in &mut s.lines {
        l.path = abs(&l.path);
        abs_masks(&mut l.select);
        abs_source(&mut l.color);
        if let Some(f) = &mut l.filter {
            abs_source(f);
        }
    }
    for p in &mut s.points {
        p.path = abs(&p.path);
        abs_source(&mut p.color);
    }
    for o in &mut s.overlays {
        o.path = abs(&o.path);
        if let Some(l) = &mut o.lut {
            *l = abs(l);
        }
    }
    toml::to_string(&s).map_err(|e| format!("writing the scene as TOML: {e}"))
}

/// Checks a selection's values (each ROI and range as `tubes::select` requires) and resolves
/// its masks' relative paths against `dir`; `key` names it (`tubes[0].select`).
fn check_select(sel: &mut SelectSpec, dir: &Path, key: &str) -> Result<(), String> {
    let at = |k: &str, why: String| format!("scene key {key}.{k}: {why}");
    for (k, list) in [
        ("include_spheres", &sel.include_spheres),
        ("exclude_spheres", &sel.exclude_spheres),
    ] {
        for s in list {
            tubes::select::Roi::sphere(*s).map_err(|e| at(k, e))?;
        }
    }
    for (k, list) in [
        ("include_boxes", &sel.include_boxes),
        ("exclude_boxes", &sel.exclude_boxes),
    ] {
        for b in list {
            tubes::select::Roi::cuboid(*b).map_err(|e| at(k, e))?;
        }
    }
    for (k, list) in [
        ("include_masks", &mut sel.include_masks),
        ("exclude_masks", &mut sel.exclude_masks),
    ] {
        for m in list.iter_mut() {
            let (p, label) = tubes::select::split_mask(m).map_err(|e| at(k, e))?;
            if Path::new(p).is_relative() {
                let joined = dir.join(p).display().to_string();
                *m = match label {
                    Some(_) => format!("{joined}{}", &m[p.len()..]),
                    None => joined,
                };
            }
        }
    }
    // Masks are read when the scene is modelled; here only the values are checked.
    crate::tube_sets::selection(sel, &|k| crate::tube_sets::scene_key(key, k), false).map(|_| ())
}

/// Checks `[annotate]`: a positive finite or `"auto"` scale bar, a colour bar source that names
/// an entry with scalar colouring, a colour, text of reasonable length.
fn check_annotate(s: &Scene) -> Result<(), String> {
    let a = &s.annotate;
    let bad = |key: &str, why: String| Err(format!("scene key annotate.{key}: {why}"));
    match &a.scale_bar {
        Some(ScaleBarSpec::Length(l)) if !(l.is_finite() && *l > 0.0 && *l <= 1e15) => {
            return bad(
                "scale_bar",
                format!("{l} is not a positive length of at most 1e15"),
            )
        }
        Some(ScaleBarSpec::Word(w)) if w != "auto" => {
            return bad("scale_bar", format!("'{w}': give a length or \"auto\""))
        }
        _ => {}
    }
    for (k, t) in [
        ("title", &a.title),
        ("units", &a.units),
        ("colorbar_label", &a.colorbar_label),
        ("colorbar_units", &a.colorbar_units),
    ] {
        if let Some(t) = t {
            if t.chars().count() > 200 || t.chars().any(char::is_control) {
                return bad(k, "at most 200 characters, no control characters".into());
            }
            let missing = crate::annotate::missing_glyphs(t);
            if !missing.is_empty() {
                let shown: String = missing.iter().take(8).collect();
                return bad(
                    k,
                    format!(
                        "the bundled font (DejaVu Sans) has no glyph for {} of its characters \
                         ({shown}{}): they would be drawn as empty boxes",
                        missing.len(),
                        if missing.len() > 8 { "..." } else { "" }
                    ),
                );
            }
        }
    }
    if let Some(c) = &a.color {
        c.rgb()
            .map_err(|e| format!("scene key annotate.color: {e}"))?;
    }
    if let Some(src) = &a.colorbar {
        let scalar = |c: &str| c.starts_with("scalar:") || c.starts_with("volume:");
        // An index as written by the entries' own keys (`lines.0`, not `lines.00`).
        let index = |n: &str| n.parse::<usize>().ok().filter(|i| i.to_string() == n);
        // What keeps the source from having a colour bar (`None`: nothing).
        let entry = |kind: &str, n: &str, colors: Vec<&str>| -> Option<String> {
            match index(n) {
                None => Some(format!("'{n}' is not an index of [[{kind}]]")),
                Some(i) if i >= colors.len() => Some(match colors.len() {
                    0 => format!("the scene has no [[{kind}]] entry"),
                    1 => format!("the scene has one [[{kind}]] entry ({kind}.0)"),
                    k => format!(
                        "the scene has {k} [[{kind}]] entries ({kind}.0 to {kind}.{})",
                        k - 1
                    ),
                }),
                Some(i) if !scalar(colors[i]) => Some(format!(
                    "{kind}.{i} is coloured '{}', not by scalar:NAME or volume:PATH",
                    colors[i]
                )),
                Some(_) => None,
            }
        };
        let why = match src.split_once('.') {
            None if src == "volume" => match &s.volume {
                None => Some("the scene has no volume".to_string()),
                Some(v) if v.iso.is_some() => {
                    Some("the volume is drawn as an isosurface ([volume.iso])".to_string())
                }
                Some(_) => None,
            },
            Some(("tubes", n)) => entry(
                "tubes",
                n,
                s.tubes.iter().map(|t| t.color.as_str()).collect(),
            ),
            Some(("lines", n)) => entry(
                "lines",
                n,
                s.lines.iter().map(|l| l.color.as_str()).collect(),
            ),
            Some(("points", n)) => entry(
                "points",
                n,
                s.points.iter().map(|p| p.color.as_str()).collect(),
            ),
            Some(("slices", n)) => match index(n) {
                None => Some(format!("'{n}' is not an index of [[slices]]")),
                Some(i) if i >= s.slices.len() => Some(match s.slices.len() {
                    0 => "the scene has no [[slices]] entry".to_string(),
                    1 => "the scene has one [[slices]] entry (slices.0)".to_string(),
                    k => format!("the scene has {k} [[slices]] entries (slices.0 to slices.{})", k - 1),
                }),
                Some(i) => s.slices[i].volume.as_ref().and_then(|name| {
                    s.overlays
                        .iter()
                        .any(|o| &o.name == name && o.labels)
                        .then(|| format!("slices.{i} shows label overlay '{name}' (its colours name labels, not a scale)"))
                }),
            },
            Some(("overlays", name)) => match s.overlays.iter().find(|o| o.name == name) {
                None => Some(format!(
                    "no overlay is named '{name}' (overlays: {})",
                    if s.overlays.is_empty() {
                        "none".to_string()
                    } else {
                        s.overlays
                            .iter()
                            .map(|o| o.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    }
                )),
                Some(o) if o.labels => Some(format!(
                    "overlay '{name}' is a label overlay (its colours name labels, not a scale)"
                )),
                Some(_) => None,
            },
            _ => Some("not a source of a colour bar".to_string()),
        };
        if let Some(why) = why {
            // The sources this scene has, so that the error offers only what would work.
            let mut have: Vec<String> = vec![];
            if s.volume
                .as_ref()
                .is_some_and(|v| v.render && v.iso.is_none())
            {
                have.push("volume".into());
            }
            // (Under the illustrative method every surface is drawn in its one ink.)
            let inked = s.render.method == Method::Illustrative;
            for (kind, colors) in [
                (
                    "tubes",
                    s.tubes.iter().map(|t| t.color.as_str()).collect::<Vec<_>>(),
                ),
                ("lines", s.lines.iter().map(|l| l.color.as_str()).collect()),
                (
                    "points",
                    s.points.iter().map(|p| p.color.as_str()).collect(),
                ),
            ]
            .into_iter()
            .filter(|_| !inked)
            {
                for (i, c) in colors.iter().enumerate() {
                    if scalar(c) {
                        have.push(format!("{kind}.{i}"));
                    }
                }
            }
            let label = |name: &str| s.overlays.iter().any(|o| o.name == name && o.labels);
            for (i, sl) in s.slices.iter().enumerate() {
                if !sl.volume.as_deref().is_some_and(label) {
                    have.push(format!("slices.{i}"));
                }
            }
            for o in s.overlays.iter().filter(|o| !o.labels) {
                have.push(format!("overlays.{}", o.name));
            }
            let have = match (s.render.bits == 1, have.is_empty()) {
                (true, _) => "none (a 1-bit image, render.bits = 1, shows no colour bar)".into(),
                (false, true) => "none (a drawn volume, an entry coloured by scalar:NAME or \
                                  volume:PATH, a scalar overlay or a slice would give one)"
                    .to_string(),
                (false, false) => have.join(", "),
            };
            return bad(
                "colorbar",
                format!("'{src}': {why}; this scene's colour bars: {have}"),
            );
        }
        if s.render.bits == 1 {
            return bad(
                "colorbar",
                format!(
                    "'{src}': a 1-bit image (render.bits = 1) cannot show a colour bar's colours"
                ),
            );
        }
    }
    Ok(())
}

/// `[[slices]]`, `[[overlays]]` and the volume's window keys: values, names and paths (made
/// relative to `dir`).
fn check_slices(s: &mut Scene, dir: &Path) -> Result<(), String> {
    let bad = |key: String, why: String| Err(format!("scene key {key}: {why}"));
    // The shaders map windows in f32: their ends and width must be finite and non-zero there.
    let window = |key: String, w: &Option<Window>| match w {
        Some(Window::Values(w)) if !f32_window(*w) => bad(
            key,
            format!(
                "{w:?}: two finite values at least 1.2e-38 and at most 3.4e38 apart are \
                 needed (its ends and its width are single-precision numbers)"
            ),
        ),
        Some(Window::Named(n)) if n != "full" && n != "robust" => bad(
            key,
            format!("'{n}' is not \"full\", \"robust\" or [lo, hi]"),
        ),
        _ => Ok(()),
    };
    let cmap = |key: String, c: &Option<String>| match c {
        Some(c) => c
            .parse::<volume::colormap::Colormap>()
            .map(|_| ())
            .or_else(|e| bad(key, e)),
        None => Ok(()),
    };
    let unit = |key: String, v: f64| {
        if (0.0..=1.0).contains(&v) {
            Ok(())
        } else {
            bad(key, format!("{v} is not in [0, 1]"))
        }
    };
    for (i, t) in s.tubes.iter().enumerate() {
        cmap(format!("tubes[{i}].colormap"), &t.colormap)?;
    }
    for (i, l) in s.lines.iter().enumerate() {
        cmap(format!("lines[{i}].colormap"), &l.colormap)?;
    }
    for (i, p) in s.points.iter().enumerate() {
        cmap(format!("points[{i}].colormap"), &p.colormap)?;
    }
    if let Some(v) = &s.volume {
        window("volume.window".into(), &v.window)?;
        cmap("volume.colormap".into(), &v.colormap)?;
        if let Some(o) = v.opacity {
            unit("volume.opacity".into(), o)?;
        }
    }
    let mut names = std::collections::HashSet::new();
    for (i, o) in s.overlays.iter_mut().enumerate() {
        let key = |k: &str| format!("overlays[{i}].{k}");
        if o.name.is_empty() || !names.insert(o.name.clone()) {
            return bad(key("name"), format!("'{}' is empty or repeated", o.name));
        }
        if o.path.is_relative() {
            o.path = dir.join(&o.path);
        }
        if let Some(l) = &mut o.lut {
            if l.is_relative() {
                *l = dir.join(&*l);
            }
        }
        window(key("range"), &o.range)?;
        cmap(key("colormap"), &o.colormap)?;
        unit(key("opacity"), o.opacity)?;
        if let Some(m) = &o.transform {
            crate::tube_sets::transform_matrix(m, &key("transform"))?;
        }
        if !o.labels && (o.lut.is_some() || o.show.is_some()) {
            return bad(
                key(if o.lut.is_some() { "lut" } else { "show" }),
                "lut and show are for label overlays (labels = true)".into(),
            );
        }
        if let Some(l) = o.show.iter().flatten().find(|l| !(0..=65535).contains(*l)) {
            return bad(key("show"), format!("label {l} is not in 0..65535"));
        }
        if o.labels && (o.range.is_some() || o.colormap.is_some()) {
            return bad(
                key(if o.range.is_some() {
                    "range"
                } else {
                    "colormap"
                }),
                "a label overlay takes its colours from lut, not range or colormap".into(),
            );
        }
    }
    if let Some(v) = &s.volume {
        if v.iso.is_some() && !v.render {
            return bad(
                "volume.render".into(),
                "false with [volume.iso]: the isosurface is the volume's drawing; leave [volume.iso] out".into(),
            );
        }
        if v.iso.is_some()
            && matches!(
                s.render.method.desc().volume,
                engine::method::VolumeShading::Projection(_)
            )
        {
            return bad(
                "render.method".into(),
                format!(
                    "{:?} projects the volume's values and [volume.iso] draws the volume as an \
                     isosurface: choose one",
                    s.render.method
                )
                .to_lowercase(),
            );
        }
        if v.iso.is_some() {
            if let Some(i) = s.tubes.iter().position(|t| t.opacity < 1.0) {
                return bad(
                    format!("tubes[{i}].opacity"),
                    "translucent tubes are not drawn with an isosurface ([volume.iso])".into(),
                );
            }
        }
    }
    if let Some(i) = s.overlays.iter().position(|o| o.volume_blend) {
        let drawn = s
            .volume
            .as_ref()
            .is_some_and(|v| v.render && v.iso.is_none());
        let projection = matches!(
            s.render.method.desc().volume,
            engine::method::VolumeShading::Projection(_)
        );
        if !drawn || projection {
            return bad(
                format!("overlays[{i}].volume_blend"),
                "needs the volume drawn by its transfer function (volume.render, not [volume.iso], not mip or minip)".into(),
            );
        }
    }
    if s.overlays.iter().filter(|o| o.volume_blend).count() > 1 {
        return bad(
            "overlays".into(),
            "volume_blend is on for more than one overlay; at most one is blended into the volume"
                .into(),
        );
    }
    if (!s.slices.is_empty() || !s.overlays.is_empty())
        && s.volume.as_ref().is_none_or(|v| v.iso.is_some())
    {
        return bad(
            "slices".into(),
            "slices and overlays need a [volume] (its grid is theirs; drawn or not, volume.render), not an isosurface ([volume.iso])"
                .into(),
        );
    }
    // The objects' transforms, checked here so that `umbra scene` refuses what rendering would.
    let transforms = (s.tubes.iter().map(|t| ("tubes", t.transform.as_ref())))
        .enumerate()
        .chain(
            s.lines
                .iter()
                .map(|l| ("lines", l.transform.as_ref()))
                .enumerate(),
        )
        .chain(
            s.points
                .iter()
                .map(|p| ("points", p.transform.as_ref()))
                .enumerate(),
        );
    for (i, (what, m)) in transforms {
        if let Some(m) = m {
            crate::tube_sets::transform_matrix(m, &format!("scene key {what}[{i}].transform"))?;
        }
    }
    for (i, sl) in s.slices.iter().enumerate() {
        let key = |k: &str| format!("slices[{i}].{k}");
        match (&sl.axis, &sl.normal) {
            (Some(_), Some(_)) | (None, None) => {
                return bad(key("axis"), "give axis or normal (one of them)".into())
            }
            (None, Some(n)) => {
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if !(l.is_finite() && l > 1e-12) {
                    return bad(key("normal"), format!("{n:?} is not a direction"));
                }
            }
            _ => {}
        }
        if let Some(p) = sl.position {
            if !(p.is_finite() && p.abs() <= volume::MAX_COORDINATE) {
                return bad(key("position"), format!("{p} is not a finite position"));
            }
        }
        if let Some(v) = &sl.volume {
            if !s.overlays.iter().any(|o| &o.name == v) {
                return bad(
                    key("volume"),
                    format!("'{v}' is not the name of an [[overlays]] entry"),
                );
            }
        }
        window(key("window"), &sl.window)?;
        cmap(key("colormap"), &sl.colormap)?;
        let shows_labels = sl
            .volume
            .as_ref()
            .is_some_and(|v| s.overlays.iter().any(|o| &o.name == v && o.labels));
        if shows_labels && (sl.window.is_some() || sl.colormap.is_some()) {
            return bad(
                key(if sl.window.is_some() { "window" } else { "colormap" }),
                "a slice showing a label overlay takes its colours from the overlay's lut, not window or colormap".into(),
            );
        }
        unit(key("opacity"), sl.opacity)?;
        if let Some(w) = sl.slab {
            if !(w.is_finite() && w > 0.0) {
                return bad(key("slab"), format!("{w} is not a positive thickness"));
            }
        }
    }
    Ok(())
}

/// Whether `[lo, hi]` can be mapped in single precision: finite ends and a finite width of at
/// least the smallest normal f32.
fn f32_window(w: [f64; 2]) -> bool {
    let (a, b) = (w[0] as f32, w[1] as f32);
    // A width under the smallest normal f32 is flushed to zero by the shaders (lavapipe).
    a.is_finite() && b.is_finite() && (b - a).is_finite() && (b - a).abs() >= f32::MIN_POSITIVE
}

/// Checks a halo's ranges; `key` names it (`lines[0].halo`).
fn check_halo(h: &HaloSpec, key: &str) -> Result<(), String> {
    let bad = |k: &str, why: String| Err(format!("scene key {key}.{k}: {why}"));
    if !(h.width >= 1.0 && h.width <= 64.0) {
        return bad("width", format!("{} is not in [1, 64]", h.width));
    }
    if !(0.0..=1.0).contains(&h.d_max) {
        return bad("d_max", format!("{} is not in [0, 1]", h.d_max));
    }
    if !(0.0..=1.0).contains(&h.depth_cue) {
        return bad("depth_cue", format!("{} is not in [0, 1]", h.depth_cue));
    }
    Ok(())
}

/// A `volume:PATH` source (a colour or a filter) with a relative path made relative to the
/// scene's folder `dir`, as every other data path of a scene; other sources unchanged.
fn resolve_volume_source(source: &mut String, dir: &Path) {
    if let Some(p) = source.strip_prefix("volume:") {
        if Path::new(p).is_relative() {
            *source = format!("volume:{}", dir.join(p).display());
        }
    }
}

/// Checks ranges and resolves relative paths.
fn validate(s: &mut Scene, dir: &Path) -> Result<(), String> {
    let bad = |key: &str, why: String| Err(format!("scene key {key}: {why}"));
    // "none": no colour bar (what an override says to one the file sets).
    if s.annotate.colorbar.as_deref() == Some("none") {
        s.annotate.colorbar = None;
    }
    check_annotate(s)?;
    let c = &s.camera;
    if !(c.fov_y > 0.0 && c.fov_y < 180.0) {
        return bad(
            "camera.fov_y",
            format!("{} is not in (0, 180) degrees", c.fov_y),
        );
    }
    if !(c.distance.is_finite() && c.distance > 1.0) {
        return bad(
            "camera.distance",
            format!(
                "{} must be a finite number above 1 (bounding-sphere radii)",
                c.distance
            ),
        );
    }
    for (key, v) in [
        ("camera.azimuth", c.azimuth),
        ("camera.elevation", c.elevation),
    ] {
        if !v.is_finite() {
            return bad(key, format!("{v} is not a finite angle"));
        }
    }
    for (key, v) in [
        ("camera.eye", c.eye),
        ("camera.target", c.target),
        ("camera.up", Some(c.up)),
    ] {
        if let Some(v) = v.filter(|v| {
            !v.iter()
                .all(|x| x.is_finite() && x.abs() <= volume::MAX_COORDINATE)
        }) {
            return bad(key, format!("{v:?} is not a finite point"));
        }
    }
    if c.up == [0.0; 3] {
        return bad("camera.up", "[0, 0, 0] has no direction".into());
    }
    for (key, v) in [("camera.near", c.near), ("camera.far", c.far)] {
        if let Some(v) = v.filter(|v| !(v.is_finite() && *v > 0.0)) {
            return bad(key, format!("{v} is not a positive finite distance"));
        }
    }
    if let (Some(n), Some(f)) = (c.near, c.far) {
        if !(n > 0.0 && f > n) {
            return bad(
                "camera.near",
                format!("near {n} and far {f} need 0 < near < far"),
            );
        }
    }
    if let Some(h) = c.height {
        if !(h.is_finite() && h > 0.0 && h <= volume::MAX_COORDINATE) {
            return bad(
                "camera.height",
                format!(
                    "{h} is not a positive finite height up to {:e}",
                    volume::MAX_COORDINATE
                ),
            );
        }
    }
    let l = &s.light;
    for (key, v) in [
        ("light.ambient", l.ambient),
        ("light.diffuse", l.diffuse),
        ("light.specular", l.specular),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return bad(key, format!("{v} is not a finite weight of at least 0"));
        }
    }
    if !(l.shininess.is_finite() && l.shininess > 0.0) {
        return bad(
            "light.shininess",
            format!("{} is not a positive exponent", l.shininess),
        );
    }
    s.background
        .rgb()
        .or_else(|e| bad("background", e).map(|()| [0.0; 3]))?;
    if let Some(v) = &mut s.volume {
        if v.path.is_relative() {
            v.path = dir.join(&v.path);
        }
        if let Some(i) = &mut v.iso {
            if let Some(f) = &mut i.fields {
                if f.is_relative() {
                    *f = dir.join(&*f);
                }
            }
            if !i.value.is_finite() {
                return bad("volume.iso.value", "must be finite".into());
            }
            i.color
                .rgb()
                .or_else(|e| bad("volume.iso.color", e).map(|()| [0.0; 3]))?;
            if let Err(e) = i.sky.parse::<volume::occlusion_shading::Sky>() {
                return bad("volume.iso.sky", e);
            }
            if !(i.gamma > 0.0 && i.gamma.is_finite()) {
                return bad(
                    "volume.iso.gamma",
                    format!("{} is not a positive finite number", i.gamma),
                );
            }
            if !(i.offset >= 0.0 && i.offset.is_finite()) {
                return bad("volume.iso.offset", format!("{} must be >= 0", i.offset));
            }
        }
        let t = &v.transfer;
        const PRESETS: [&str; 4] = ["grey", "bone", "fire", "cool-warm"];
        if t.points.is_empty() && !PRESETS.contains(&t.preset.as_str()) {
            return bad(
                "volume.transfer.preset",
                format!("'{}' is not one of {}", t.preset, PRESETS.join(", ")),
            );
        }
        if !t.points.is_empty() {
            let d = TransferSpec::default();
            if !t.range.is_full() {
                return bad(
                    "volume.transfer.range",
                    "spans a preset's ramp; points carry their own values".into(),
                );
            }
            if t.preset != d.preset {
                return bad(
                    "volume.transfer.preset",
                    format!(
                        "'{}' with points: a preset's ramp or points, not both (points carry \
                         their own colours)",
                        t.preset
                    ),
                );
            }
            if t.extinction != d.extinction {
                return bad(
                    "volume.transfer.extinction",
                    format!(
                        "{} with points: the extinction at a preset's top; points carry their \
                         own",
                        t.extinction
                    ),
                );
            }
        }
        match &t.range {
            TransferRange::Named(n) if n == "full" || n == "robust" => {}
            TransferRange::Named(n) => {
                return bad(
                    "volume.transfer.range",
                    format!("'{n}' is not \"full\", \"robust\" or [lo, hi]"),
                )
            }
            TransferRange::Values([lo, hi]) => {
                if !((*lo as f32).is_finite()
                    && (*hi as f32).is_finite()
                    && (*lo as f32) < (*hi as f32))
                {
                    return bad(
                        "volume.transfer.range",
                        format!("[{lo}, {hi}]: two values finite in single precision, lo below hi there, are needed"),
                    );
                }
            }
        }
        if !(t.extinction.is_finite() && t.extinction >= 0.0) {
            return bad(
                "volume.transfer.extinction",
                format!("{} is not a finite extinction of at least 0", t.extinction),
            );
        }
        for (i, p) in t.points.iter().enumerate() {
            p.color.rgb().or_else(|e| {
                bad(&format!("volume.transfer.points[{i}].color"), e).map(|()| [0.0; 3])
            })?;
            if !(p.extinction >= 0.0 && p.extinction.is_finite() && p.value.is_finite()) {
                return bad(
                    &format!("volume.transfer.points[{i}]"),
                    "value must be finite and extinction finite and >= 0".into(),
                );
            }
            // Both devices interpolate in single precision: a value past it (the CPU took
            // 1e39 as the first point's colour, the GPU as nothing) is refused, as windows are.
            if !(p.value as f32).is_finite() {
                return bad(
                    &format!("volume.transfer.points[{i}].value"),
                    format!(
                        "{}: values must be finite in single precision (at most 3.4e38)",
                        p.value
                    ),
                );
            }
        }
        if let (Some(a), Some(b)) = (t.points.first(), t.points.last()) {
            if !((b.value as f32) - (a.value as f32)).is_finite() {
                return bad(
                    "volume.transfer.points",
                    format!(
                        "values from {} to {} span more than single precision holds (at most \
                         3.4e38 apart)",
                        a.value, b.value
                    ),
                );
            }
        }
        let twod = t.points.iter().filter(|p| p.gradient.is_some()).count();
        if twod != 0 && twod != t.points.len() {
            return bad(
                "volume.transfer.points",
                "either every point has a gradient (2-D) or none does".into(),
            );
        }
        if twod == 0 && t.points.windows(2).any(|w| w[1].value < w[0].value) {
            return bad("volume.transfer.points", "values must not decrease".into());
        }
        // 2-D: each row (the points of one gradient, in the order written) as a 1-D function
        // (a decreasing row was sorted silently).
        for (i, p) in t.points.iter().enumerate().filter(|_| twod != 0) {
            let before = t.points[..i]
                .iter()
                .rev()
                .find(|q| q.gradient == p.gradient);
            if let Some(q) = before.filter(|q| p.value < q.value) {
                return bad(
                    &format!("volume.transfer.points[{i}].value"),
                    format!(
                        "{} after {} in the row of gradient {}: values must not decrease \
                         within a row",
                        p.value,
                        q.value,
                        p.gradient.unwrap_or(0.0)
                    ),
                );
            }
        }
        if t.points
            .iter()
            .any(|p| p.gradient.is_some_and(|g| !(g >= 0.0 && g.is_finite())))
        {
            return bad(
                "volume.transfer.points",
                "gradient magnitudes must be finite and >= 0".into(),
            );
        }
    }
    for (i, t) in s.tubes.iter_mut().enumerate() {
        if t.path.is_relative() {
            t.path = dir.join(&t.path);
        }
        let max_r = tubes::tube_mesh::TubeOptions::MAX_RADIUS;
        if !(t.radius > 0.0 && t.radius <= max_r) {
            return bad(
                &format!("tubes[{i}].radius"),
                format!("{} is not a positive radius up to {max_r:e}", t.radius),
            );
        }
        if !(t.tolerance.is_finite() && t.tolerance > 0.0) {
            return bad(
                &format!("tubes[{i}].tolerance"),
                format!("{} is not a positive finite number", t.tolerance),
            );
        }
        if !(3..=256).contains(&t.sides) {
            return bad(
                &format!("tubes[{i}].sides"),
                format!("{} is not a side count from 3 to 256", t.sides),
            );
        }
        if !(0.0..=1.0).contains(&t.opacity) {
            return bad(
                &format!("tubes[{i}].opacity"),
                format!("{} is not in [0, 1]", t.opacity),
            );
        }
        check_color_source(&t.color).map_err(|why| format!("scene key tubes[{i}].color: {why}"))?;
        resolve_volume_source(&mut t.color, dir);
        if let Some(sel) = &mut t.select {
            check_select(sel, dir, &format!("tubes[{i}].select"))?;
        }
    }
    for (i, p) in s.points.iter_mut().enumerate() {
        if p.path.is_relative() {
            p.path = dir.join(&p.path);
        }
        if !(p.size > 0.0 && p.size <= 1e15) {
            return bad(
                &format!("points[{i}].size"),
                format!("{} is not a positive diameter up to 1e15", p.size),
            );
        }
        if p.color == "direction" {
            return bad(
                &format!("points[{i}].color"),
                "points have no direction: use scalar:NAME, volume:PATH or #rrggbb".into(),
            );
        }
        check_color_source(&p.color)
            .map_err(|why| format!("scene key points[{i}].color: {why}"))?;
        resolve_volume_source(&mut p.color, dir);
        if let Some(h) = &p.halo {
            check_halo(h, &format!("points[{i}].halo"))?;
        }
    }
    for (i, l) in s.lines.iter_mut().enumerate() {
        if l.path.is_relative() {
            l.path = dir.join(&l.path);
        }
        if let Some(sel) = &mut l.select {
            check_select(sel, dir, &format!("lines[{i}].select"))?;
        }
        if !(l.width > 0.0 && l.width.is_finite()) {
            return bad(
                &format!("lines[{i}].width"),
                format!("{} is not a positive finite number", l.width),
            );
        }
        if l.width_unit == WidthUnit::Pixels && l.width > 256.0 {
            return bad(
                &format!("lines[{i}].width"),
                format!("{} pixels: at most 256", l.width),
            );
        }
        if l.width_unit == WidthUnit::World && l.width > 1e15 {
            return bad(
                &format!("lines[{i}].width"),
                format!("{} world units: at most 1e15", l.width),
            );
        }
        check_color_source(&l.color).map_err(|why| format!("scene key lines[{i}].color: {why}"))?;
        resolve_volume_source(&mut l.color, dir);
        if let Some(t) = &l.trail {
            let key = |k: &str| format!("lines[{i}].trail.{k}");
            if l.time.is_none() {
                return bad(
                    &format!("lines[{i}].trail"),
                    "needs a time attribute: time = \"scalar:NAME\"".into(),
                );
            }
            if !t.now.is_finite() {
                return bad(&key("now"), format!("{} is not finite", t.now));
            }
            for (k, v) in [("back", t.back), ("forward", t.forward)] {
                if !(v >= 0.0 && v.is_finite()) {
                    return bad(&key(k), format!("{v} is not a duration >= 0"));
                }
            }
            if !(0.0..1.0).contains(&t.start) {
                return bad(&key("start"), format!("{} is not in [0, 1)", t.start));
            }
            if !(0.0..=1.0).contains(&t.min_width) {
                return bad(
                    &key("min_width"),
                    format!("{} is not in [0, 1]", t.min_width),
                );
            }
        }
        if let Some(t) = &l.taper {
            if !(t.u > 0.0 && t.u <= 0.5) {
                return bad(
                    &format!("lines[{i}].taper.u"),
                    format!("{} is not in (0, 0.5]", t.u),
                );
            }
            if t.vertices == 0 || t.vertices > 1000 {
                return bad(
                    &format!("lines[{i}].taper.vertices"),
                    format!("{} is not in 1..=1000", t.vertices),
                );
            }
        }
        if let Some(f) = &mut l.filter {
            if f.starts_with("volume:") {
                resolve_volume_source(f, dir);
            } else if f.strip_prefix("scalar:").is_none_or(|n| n.is_empty()) {
                return bad(
                    &format!("lines[{i}].filter"),
                    format!("'{f}' is not scalar:NAME or volume:PATH"),
                );
            }
        }
        if !l.filter_min.is_finite() {
            return bad(
                &format!("lines[{i}].filter_min"),
                format!("{} is not a finite value", l.filter_min),
            );
        }
        if !(l.filter_taper >= 0.0 && l.filter_taper.is_finite()) {
            return bad(
                &format!("lines[{i}].filter_taper"),
                format!("{} is not a finite width at least 0", l.filter_taper),
            );
        }
        if let Some(h) = &l.halo {
            check_halo(h, &format!("lines[{i}].halo"))?;
        }
        if let Some(t) = &l.time {
            if !t.starts_with("scalar:") || t.len() == "scalar:".len() {
                return bad(
                    &format!("lines[{i}].time"),
                    format!("'{t}' is not scalar:NAME"),
                );
            }
        }
        if l.proxy_radius.is_some_and(|r| !(r >= 0.0 && r.is_finite())) {
            return bad(
                &format!("lines[{i}].proxy_radius"),
                format!("{:?} is not a radius >= 0", l.proxy_radius.unwrap()),
            );
        }
    }
    check_slices(s, dir)?;
    if s.clip.len() > occlusion::emission_absorption::MAX_CLIP {
        return bad(
            "clip",
            format!(
                "{} planes; at most {} are drawn",
                s.clip.len(),
                occlusion::emission_absorption::MAX_CLIP
            ),
        );
    }
    for (i, c) in s.clip.iter().enumerate() {
        let n = glam::DVec3::from(c.normal);
        if !n.is_finite() || n.length() < 1e-12 {
            return bad(
                &format!("clip[{i}].normal"),
                format!("{:?} is not a finite nonzero direction", c.normal),
            );
        }
        if !(c.offset.is_finite() && c.offset.abs() <= volume::MAX_COORDINATE) {
            return bad(
                &format!("clip[{i}].offset"),
                format!(
                    "{} is not a finite offset within {:e}",
                    c.offset,
                    volume::MAX_COORDINATE
                ),
            );
        }
    }
    let r = &s.render;
    for (key, v) in [("render.width", r.width), ("render.height", r.height)] {
        if !(1..=16384).contains(&v) {
            return bad(key, format!("{v} pixels is not within 1..16384"));
        }
    }
    if r.slices.is_some() && r.slice_distance.is_some() {
        return bad(
            "render.slices",
            "give slices or slice_distance, not both".into(),
        );
    }
    if r.slices == Some(0) {
        return bad("render.slices", "must be positive".into());
    }
    if let Some(d) = r.slice_distance.filter(|d| !(d.is_finite() && *d > 0.0)) {
        return bad(
            "render.slice_distance",
            format!("{d} is not a positive finite distance"),
        );
    }
    if !(1..=engine::gbuffer::MAX_PEEL_LAYERS).contains(&r.translucent_layers) {
        return bad(
            "render.translucent_layers",
            format!(
                "{} is not in 1..{}",
                r.translucent_layers,
                engine::gbuffer::MAX_PEEL_LAYERS
            ),
        );
    }
    if r.slices.is_some_and(|n| !(1..=16384).contains(&n)) {
        return bad("render.slices", "1 to 16384".into());
    }
    // The passes check their own settings; the scene names the keys they came from.
    let slices = engine::slice_pass::SliceSettings {
        occlusion: true,
        cell: r.occlusion_cell,
        step: r.occlusion_step,
        cone: r.occlusion_model == OcclusionModel::Cone,
        phong: false,
        projection: None,
        column: r.geometry_shadow == GeometryShadow::Column,
        theta_deg: r.theta,
        blur_samples: r.blur_samples,
        geometry_extinction: r.geometry_extinction,
        light: [0.0; 4],
        partial_layer: None,
        geometry_light: false,
    };
    if let Err(e) = slices.check() {
        let key = match e.field {
            "theta_deg" => "render.theta",
            "blur_samples" => "render.blur_samples",
            "cell" => "render.occlusion_cell",
            "step" => "render.occlusion_step",
            _ => "render.geometry_extinction",
        };
        return bad(key, e.problem);
    }
    let vicinity = engine::vicinity::VicinitySettings {
        samples: r.vicinity_samples,
        distance: r.vicinity_distance,
        theta_deg: r.theta,
        bias: r.vicinity_bias.unwrap_or(0.0),
    };
    if let Err(e) = vicinity.check() {
        let key = match e.field {
            "samples" => "render.vicinity_samples",
            "distance" => "render.vicinity_distance",
            _ => "render.vicinity_bias",
        };
        return bad(key, e.problem);
    }
    if let Err(e) = r.lineao.settings([0.3, 0.7, 0.3, 32.0]).kernel.check() {
        let key = match e.field {
            "r0_widths" => "r0",
            f => f,
        };
        return bad(&format!("render.lineao.{key}"), e.problem);
    }
    if r.lineao.guard > 1024 {
        return bad(
            "render.lineao.guard",
            format!("{} pixels: at most 1024", r.lineao.guard),
        );
    }
    for (k, c) in [
        ("line", &r.illustrative.line),
        ("halo", &r.illustrative.halo),
    ] {
        c.rgb()
            .or_else(|e| bad(&format!("render.illustrative.{k}"), e).map(|()| [0.0; 3]))?;
    }
    for (k, v) in [
        ("render.eye_separation", r.eye_separation),
        ("render.convergence", r.convergence),
    ] {
        if let Some(v) = v {
            if !(v > 0.0 && v <= 1e15) {
                return bad(k, format!("{v} is not a positive distance of at most 1e15"));
            }
        }
    }
    if ![1, 8].contains(&r.bits) {
        return bad("render.bits", format!("{} is not 1 or 8", r.bits));
    }
    if r.bits == 1 && r.stereo != Stereo::None {
        return bad(
            "render.bits",
            "1: a 1-bit image cannot hold an anaglyph's two colours (render.stereo)".into(),
        );
    }
    if ![1, 2, 4, 8].contains(&r.msaa) {
        return bad("render.msaa", format!("{} is not 1, 2, 4 or 8", r.msaa));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fraction where a whole number belongs reads as such, in a file and in an override
    /// (serde's "invalid type: floating point `2.5`, expected i64").
    #[test]
    fn a_fraction_for_a_whole_number_says_so() {
        let text = "[volume]\npath = \"v.nii\"\n[[overlays]]\nname = \"a\"\npath = \"a.nii\"\nlabels = true\nshow = [2.5]\n";
        let e = parse(text, "s.toml", Path::new("."), &[]).unwrap_err();
        assert!(
            e.contains("2.5 is not a whole number") && !e.contains("i64"),
            "{e}"
        );
        let text = text.replace("show = [2.5]", "show = [2]");
        let e = parse(
            &text,
            "s.toml",
            Path::new("."),
            &["overlays.0.show=[2.5]".into()],
        )
        .unwrap_err();
        assert!(
            e.contains("overlays[0].show: 2.5 is not a whole number"),
            "{e}"
        );
        assert_eq!(
            plain("invalid type: string \"x\", expected f64"),
            "invalid type: string \"x\", expected f64"
        );
    }

    fn example() -> String {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/scenes/example.toml");
        std::fs::read_to_string(p).unwrap()
    }

    #[test]
    fn a_data_file_given_as_a_scene_is_named_for_what_it_is() {
        let dir = tempfile::tempdir().unwrap();
        for (name, body, kind) in [
            (
                "heart.vti",
                &b"<VTKFile type=\"ImageData\">"[..],
                "a volume file",
            ),
            ("t1.nii.gz", &b"\x1f\x8b\x08\x00"[..], "a volume file"),
            ("af.trk", &b"TRACK\0\0"[..], "a tractogram file"),
        ] {
            let p = dir.path().join(name);
            std::fs::write(&p, body).unwrap();
            let e = load(&p, &[]).unwrap_err();
            assert!(
                e.contains(kind) && e.contains("not a scene") && e.contains(name),
                "{e}"
            );
        }
        // A scene with a TOML error keeps the parser's message.
        let p = dir.path().join("s.toml");
        std::fs::write(&p, "[volume\n").unwrap();
        let e = load(&p, &[]).unwrap_err();
        assert!(
            e.contains("TOML parse error") && !e.contains("not a scene"),
            "{e}"
        );
    }

    #[test]
    fn the_documented_example_parses_with_its_values() {
        let s = parse(&example(), "example.toml", Path::new("/d"), &[]).unwrap();
        assert_eq!(s.tubes.len(), 1);
        assert_eq!(s.render.method, Method::Combined);
        assert!(s.volume.as_ref().unwrap().path.starts_with("/d"));
        assert_eq!(s.clip.len(), 1);
    }

    /// A preset's keys beside points are refused, each naming its key (they were ignored in
    /// silence); left at their defaults, or written as the defaults, they pass.
    #[test]
    fn a_presets_keys_beside_points_are_refused() {
        let pts = "points = [{ value = 0.0, color = [0, 0, 0], extinction = 0.0 }, \
                   { value = 1.0, color = [1, 1, 1], extinction = 1.0 }]\n";
        let scene =
            |extra: &str| format!("[volume]\npath = \"v.nii\"\n[volume.transfer]\n{pts}{extra}");
        for (extra, key) in [
            ("preset = \"fire\"\n", "volume.transfer.preset"),
            ("extinction = 0.3\n", "volume.transfer.extinction"),
            ("range = \"robust\"\n", "volume.transfer.range"),
        ] {
            let e = parse(&scene(extra), "s.toml", Path::new("/d"), &[]).unwrap_err();
            assert!(e.contains(key) && e.starts_with("s.toml"), "{extra}: {e}");
        }
        for extra in [
            "",
            "preset = \"grey\"\nextinction = 0.5\nrange = \"full\"\n",
        ] {
            parse(&scene(extra), "s.toml", Path::new("/d"), &[]).unwrap();
        }
        // What the viewer's editor saves when it turns a preset into points.
        let t = TransferSpec::from_points(vec![]);
        assert_eq!((t.preset.as_str(), t.extinction), ("grey", 0.5));
        assert!(t.range.is_full());
    }

    #[test]
    fn volume_sources_resolve_against_the_scene_folder_as_every_data_path() {
        let text = "[[tubes]]\npath = \"t.trk\"\ncolor = \"volume:fa.nii\"\n\
                    [[lines]]\npath = \"l.trk\"\ncolor = \"volume:sub/fa.nii\"\n\
                    filter = \"volume:md.nii\"\n\
                    [[points]]\npath = \"p.csv\"\ncolor = \"volume:/abs/fa.nii\"\n";
        let s = parse(text, "s.toml", Path::new("/scn"), &[]).unwrap();
        let v = |p: &str| format!("volume:{}", Path::new("/scn").join(p).display());
        assert_eq!(s.tubes[0].color, v("fa.nii"));
        assert_eq!(s.lines[0].color, v("sub/fa.nii"));
        assert_eq!(s.lines[0].filter.as_deref(), Some(v("md.nii").as_str()));
        assert_eq!(s.points[0].color, "volume:/abs/fa.nii");
    }

    #[test]
    fn a_scene_saved_as_toml_loads_back_the_same_from_anywhere() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/scenes");
        let out = tempfile::tempdir().unwrap();
        for name in [
            "example.toml",
            "demo.toml",
            "demo_lines.toml",
            "mni_ea.toml",
            "slices.toml",
        ] {
            // Relative to the working directory, as `umbra render datasets/scenes/x.toml`.
            let s = load(&dir.join(name), &["camera.azimuth=-42.5".into()]).unwrap();
            let text = to_toml(&s).unwrap();
            let saved = out.path().join(name);
            std::fs::write(&saved, &text).unwrap();
            let back = load(&saved, &[]).unwrap();
            // Equal but for the paths, which are now absolute, and point at the same files.
            assert_eq!(to_toml(&back).unwrap(), text, "{name}");
            let v = back.volume.as_ref().unwrap();
            assert!(
                v.path.is_absolute() && v.path.exists(),
                "{name}: {:?}",
                v.path
            );
            assert_eq!(back.camera.azimuth, -42.5);
            assert_eq!(back.render, s.render, "{name}");
        }
    }

    #[test]
    fn the_reference_key_changes_with_the_light_model_only() {
        let key = |o: &[&str]| {
            let s = parse(
                "",
                "s",
                Path::new("."),
                &o.iter().map(|x| x.to_string()).collect::<Vec<_>>(),
            )
            .unwrap();
            serde_json::to_string(&s.reference_key()).unwrap()
        };
        let base = key(&[]);
        for approx in [
            "render.method=ea",
            "render.slices=64",
            "render.blur_samples=5",
            "render.vicinity_samples=8",
            "render.vicinity_bias=0.3",
            "render.combine=product",
            "render.occlusion_cell=4",
            "render.occlusion_step=1",
            "render.occlusion_model=cone",
            "render.msaa=1",
            "render.fxaa=false",
            "render.surface_ao=none",
        ] {
            assert_eq!(key(&[approx]), base, "{approx}");
        }
        for model in [
            "render.vicinity_distance=3.0",
            "render.theta=30",
            "render.geometry_extinction=2",
            "render.geometry_shadow=column",
            "render.width=64",
            "light.ambient=0.5",
            "camera.azimuth=10",
            "background=[0, 0, 0]",
        ] {
            assert_ne!(key(&[model]), base, "{model}");
        }
    }

    #[test]
    fn line_sets_take_their_defaults_and_resolve_their_paths() {
        let s = parse(
            "[[lines]]\npath = \"a.tck\"\n[[lines]]\npath = \"/b.trk\"\nwidth = 0.2\nwidth_unit = \"world\"\nprofile = \"cylinder\"\ncolor = \"#ff0000\"\n",
            "s",
            Path::new("/data"),
            &[],
        )
        .unwrap();
        assert_eq!(s.lines.len(), 2);
        let (a, b) = (&s.lines[0], &s.lines[1]);
        assert_eq!(a.path, Path::new("/data/a.tck"));
        assert_eq!(
            (a.width, a.width_unit, a.profile),
            (2.0, WidthUnit::Pixels, LineProfile::Flat)
        );
        assert_eq!(a.color, "direction");
        assert_eq!(
            (b.width, b.width_unit, b.profile),
            (0.2, WidthUnit::World, LineProfile::Cylinder)
        );
        // Lines are part of what the ground truth depends on.
        let t = parse(
            "[[lines]]\npath = \"a.tck\"\nwidth = 3.0\n",
            "s",
            Path::new("/data"),
            &[],
        )
        .unwrap();
        let key = |s: &Scene| serde_json::to_string(&s.reference_key()).unwrap();
        assert_ne!(key(&s), key(&t));
    }

    #[test]
    fn lineao_keys_take_their_defaults_and_bad_values_name_their_key() {
        let s = parse("", "s", Path::new("."), &[]).unwrap();
        let k = s.render.lineao.settings([0.3, 0.7, 0.3, 32.0]);
        assert_eq!(k.kernel.samples, 32);
        assert_eq!(k.kernel.levels, 3);
        assert_eq!(k.guard, 64);
        assert_eq!(k.shading, LineAoShading::Phong);
        let bad = |set: &str| parse("", "s", Path::new("."), &[set.into()]).unwrap_err();
        for (set, key) in [
            ("render.lineao.levels=0", "render.lineao.levels"),
            ("render.lineao.levels=9", "render.lineao.levels"),
            ("render.lineao.samples=0", "render.lineao.samples"),
            ("render.lineao.r0=-1", "render.lineao.r0"),
            ("render.lineao.delta0=0.5", "render.lineao.delta0"),
            ("render.lineao.radius_step=-1", "render.lineao.radius_step"),
            ("render.lineao.guard=5000", "render.lineao.guard"),
            ("render.lineao.floor=2", "render.lineao.floor"),
            ("render.lineao.intensity=-1", "render.lineao.intensity"),
            ("render.height=0", "render.height"),
            ("render.width=20000", "render.width"),
            ("render.slice_distance=0", "render.slice_distance"),
            ("render.slices=0", "render.slices"),
            ("camera.height=1e20", "camera.height"),
            (
                "overlays=[{name=\"a\",path=\"a.nii\",labels=true,show=[70000]}]",
                "overlays[0].show: label 70000 is not in 0..65535",
            ),
            (
                "overlays=[{name=\"a\",path=\"a.nii\",labels=true,colormap=\"hot\"}]",
                "overlays[0].colormap",
            ),
            (
                "overlays=[{name=\"a\",path=\"a.nii\",show=[1]}]",
                "overlays[0].show",
            ),
            (
                "lines=[{path=\"a.tck\",filter=\"scalar:s\",filter_taper=-1}]",
                "lines[0].filter_taper",
            ),
            (
                "lines=[{path=\"a.tck\",width=1e20,width_unit=\"world\"}]",
                "lines[0].width: 100000000000000000000 world units: at most 1e15",
            ),
            (
                "tubes=[{path=\"a.tck\",transform=[nan,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]}]",
                "tubes[0].transform",
            ),
            (
                "points=[{path=\"a.csv\",transform=[1e300,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]}]",
                "points[0].transform",
            ),
            (
                "clip=[{normal=[0,0,1],offset=1e16}]",
                "clip[0].offset: 10000000000000000 is not a finite offset within 1e15",
            ),
        ] {
            let e = bad(set);
            assert!(e.contains(key), "{set}: {e}");
        }
        assert!(bad("render.lineao.falloff=cubic").contains("falloff"));
        // A scene's lines: proxy radius defaults by unit, and a negative one is refused.
        let l = |extra: &str| {
            parse(
                &format!("[[lines]]\npath = \"a.tck\"\n{extra}"),
                "s",
                Path::new("/d"),
                &[],
            )
        };
        assert_eq!(l("").unwrap().lines[0].proxy_radius(), 0.0);
        let world = l("width = 0.6\nwidth_unit = \"world\"\n").unwrap();
        assert!((world.lines[0].proxy_radius() - 0.3).abs() < 1e-12);
        let e = l("proxy_radius = -1.0\n").unwrap_err();
        assert!(e.contains("lines[0].proxy_radius"), "{e}");
        // Trails: their defaults, and the keys a bad one names.
        let t = l("time = \"scalar:time\"\ntrail = { now = 2.0, back = 1.0, forward = 0.5 }\n")
            .unwrap();
        let tr = t.lines[0].trail.as_ref().unwrap();
        assert_eq!((tr.start, tr.min_width), (1.0 / 3.0, 0.25));
        for (extra, key) in [
            ("trail = { now = 2.0, back = 1.0, forward = 0.5 }\n", "lines[0].trail"),
            ("time = \"speed\"\n", "lines[0].time"),
            (
                "time = \"scalar:t\"\ntrail = { now = 2.0, back = -1.0, forward = 0.5 }\n",
                "lines[0].trail.back",
            ),
            (
                "time = \"scalar:t\"\ntrail = { now = 2.0, back = 1.0, forward = 0.5, start = 1.0 }\n",
                "lines[0].trail.start",
            ),
            ("filter = \"speed\"\n", "lines[0].filter"),
            ("filter = \"scalar:fa\"\nfilter_taper = -1.0\n", "lines[0].filter_taper"),
            ("filter = \"scalar:fa\"\nfilter_min = nan\n", "lines[0].filter_min"),
            ("taper = { u = 0.7 }\n", "lines[0].taper.u"),
            ("taper = { vertices = 0 }\n", "lines[0].taper.vertices"),
            ("halo = { width = 0.5 }\n", "lines[0].halo.width"),
            ("halo = { d_max = 2.0 }\n", "lines[0].halo.d_max"),
            (
                "time = \"scalar:t\"\ntrail = { now = 2.0, back = 1.0, forward = 0.5, min_width = 2.0 }\n",
                "lines[0].trail.min_width",
            ),
        ] {
            let e = l(extra).unwrap_err();
            assert!(e.contains(key), "{extra}: {e}");
        }
    }

    #[test]
    fn an_entry_without_its_path_is_pointed_at() {
        let e = parse("[[lines]]\nwidth = 2.0\n", "s.toml", Path::new("."), &[]).unwrap_err();
        assert!(
            e.starts_with("s.toml: ")
                && e.contains("missing field `path`")
                && e.contains("names its data file with path"),
            "{e}"
        );
    }

    #[test]
    fn defaults_fill_an_empty_scene() {
        let s = parse("", "empty", Path::new("."), &[]).unwrap();
        assert_eq!(s.render, RenderSpec::default());
        assert_eq!(s.camera, CameraSpec::default());
        assert!(s.volume.is_none() && s.tubes.is_empty());
    }

    #[test]
    fn unknown_keys_name_the_key_and_line() {
        let text = "[render]\nwidth = 100\nslizes = 12\n";
        let e = parse(text, "s.toml", Path::new("."), &[]).unwrap_err();
        assert!(
            e.contains("s.toml") && e.contains("slizes") && e.contains("line 3"),
            "{e}"
        );
        let e = parse("[camera]\nfov_y = 200\n", "s.toml", Path::new("."), &[]).unwrap_err();
        assert!(e.contains("camera.fov_y"), "{e}");
        let e = parse(
            "[render]\nvicinity_samples = 119\n",
            "s",
            Path::new("."),
            &[],
        )
        .unwrap_err();
        assert!(e.contains("118"), "{e}");
    }

    #[test]
    fn two_d_transfer_rows_must_not_decrease() {
        let scene = |pts: &str| {
            format!("[volume]\npath = \"v.nrrd\"\n[volume.transfer]\npoints = [{pts}]\n")
        };
        let p = |v: f64, g: f64| {
            format!("{{value = {v}, color = [1, 1, 1], extinction = 1, gradient = {g}}},")
        };
        // Two rows, written interleaved: each non-decreasing.
        let ok = scene(&[p(0.0, 0.0), p(0.0, 40.0), p(100.0, 0.0), p(100.0, 40.0)].concat());
        parse(&ok, "s", Path::new("."), &[]).unwrap();
        // The row of gradient 0 goes 0, 300, 255: refused, naming the point.
        let bad = scene(&[p(0.0, 0.0), p(300.0, 0.0), p(0.0, 40.0), p(255.0, 0.0)].concat());
        let e = parse(&bad, "s", Path::new("."), &[]).unwrap_err();
        assert!(
            e.contains("volume.transfer.points[3].value") && e.contains("255 after 300"),
            "{e}"
        );
    }

    #[test]
    fn a_colour_bar_set_to_none_is_no_colour_bar() {
        let text = "[annotate]\ncolorbar = \"tubes.0\"\n[[tubes]]\npath = \"a.trk\"\ncolor = \"scalar:fa\"\n";
        let s = parse(
            text,
            "s",
            Path::new("."),
            &["annotate.colorbar=\"none\"".into()],
        )
        .unwrap();
        assert_eq!(s.annotate.colorbar, None);
        assert!(parse(
            text,
            "s",
            Path::new("."),
            &["annotate.colorbar=\"nope\"".into()]
        )
        .is_err());
    }

    #[test]
    fn set_overrides_by_dotted_path() {
        let text = "[render]\nwidth = 100\n[[tubes]]\npath = \"a.trk\"\n";
        let o = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let s = parse(
            text,
            "s",
            Path::new("."),
            &o(&[
                "render.width=640",
                "camera.eye=[1, 2, 3]",
                "tubes.0.radius=0.25",
                "render.method=vicinity",
            ]),
        )
        .unwrap();
        assert_eq!(s.render.width, 640);
        assert_eq!(s.camera.eye, Some([1.0, 2.0, 3.0]));
        assert_eq!(s.tubes[0].radius, 0.25);
        assert_eq!(s.render.method, Method::Vicinity);
        let e = parse(text, "s", Path::new("."), &o(&["render.nope=1"])).unwrap_err();
        assert!(e.contains("render.nope: unknown field `nope`"), "{e}");
        // A key at the top level: the message, not an empty path (": unknown field").
        let e = parse(text, "s", Path::new("."), &o(&["foo=1"])).unwrap_err();
        assert!(
            e.contains("unknown field `foo`") && !e.contains(": :"),
            "{e}"
        );
        // A typo inside the file lists every key of its table, uncut (400 characters cut the
        // list of [render]'s keys mid-word).
        let e = parse("[render]\nwidht = 5\n", "s", Path::new("."), &[]).unwrap_err();
        assert!(e.contains("`width`") && !e.contains("in all)"), "{e}");
        let e = parse(text, "s", Path::new("."), &o(&["tubes.3.radius=1"])).unwrap_err();
        assert!(e.contains("1 entries"), "{e}");
        // A bad list value is named by its key, not by the table it is in (the `[` of the
        // array was taken for a table's header: "camera: invalid length ...").
        for (set, key) in [
            ("camera.target=[1, 2]", "camera.target: "),
            ("tubes.0.color=[1]", "tubes[0].color: "),
        ] {
            let e = parse(text, "s", Path::new("."), &o(&[set])).unwrap_err();
            assert!(e.contains(key), "{set}: {e}");
        }
        // An index into a list the scene does not have names the list (it read
        // "render.[: invalid type: map, expected a sequence").
        for (set, list) in [
            ("lines.0.width=2", "'lines'"),
            ("clip.0.offset=1", "'clip'"),
            (
                "volume.transfer.points.0.value=1",
                "'volume.transfer.points'",
            ),
        ] {
            let e = parse(text, "s", Path::new("."), &o(&[set])).unwrap_err();
            assert!(e.contains(&format!("has no {list} entries")), "{set}: {e}");
        }
        assert!(parse(text, "s", Path::new("."), &o(&["render.width"])).is_err());
        // A list of values: one value set, a list the file lacks given whole, no table inside
        // a value, no negative index, no entry replaced whole.
        let bg = "background = [1.0, 1.0, 1.0]\n[[tubes]]\npath = \"a.trk\"\n";
        let s = parse(bg, "s", Path::new("."), &o(&["background.0=0.5"])).unwrap();
        assert_eq!(s.background, Color::Rgb([0.5, 1.0, 1.0]));
        for (set, want) in [
            ("camera.eye.0=1", "give the whole value (camera.eye=[...])"),
            ("background.0.x=1", "'background' holds values, not tables"),
            (
                "tubes.-1.radius=1",
                "index -1 of 'tubes'; entries count from 0",
            ),
            (
                "tubes.0={radius=1.0}",
                "an entry of 'tubes' is not replaced whole",
            ),
        ] {
            let e = parse(bg, "s", Path::new("."), &o(&[set])).unwrap_err();
            assert!(e.contains(want), "{set}: {e}");
        }
        // A bad value set by an override is named by its path, with the entry of an array of
        // tables: the key, its entry and the problem.
        for (set, want) in [
            (
                "tubes=[{path=\"a.trk\"}, {path=\"b.trk\", radius=\"big\"}]",
                "s with overrides: tubes[1].radius: invalid type: string \"big\", expected f64",
            ),
            (
                "tubes=[{path=\"a.trk\"}, {radius=1.0}]",
                "s with overrides: tubes[1]: missing field `path`",
            ),
            (
                "render.width=\"wide\"",
                "s with overrides: render.width: invalid type: string \"wide\", expected u32",
            ),
            (
                "camera.azimuth=true",
                "s with overrides: camera.azimuth: invalid type",
            ),
            // A table inside an entry names the entry too (it read "tubes.select...").
            (
                "tubes=[{path=\"a.trk\"}, {path=\"b.trk\", select={min_length=\"x\"}}]",
                "s with overrides: tubes[1].select.min_length: invalid type",
            ),
            // An unknown top-level table is the message alone (it read "clip[0].[: ...", the
            // position of another table), an unknown key of a table names the key in it (it
            // read "camera: unknown field", which the `--set` hint could not match).
            ("foo.bar=1", "s with overrides: unknown field `foo`"),
            (
                "camera.foo=1",
                "s with overrides: camera.foo: unknown field `foo`",
            ),
        ] {
            let e = parse(text, "s", Path::new("."), &o(&[set])).unwrap_err();
            assert!(e.starts_with(want), "{set}: {e}");
        }
        // Brackets in an override's key: the dotted form is named (it read "lines.select.[:
        // unknown field").
        let e = parse(text, "s", Path::new("."), &o(&["tubes[0].radius=1"])).unwrap_err();
        assert!(e.contains("(tubes.0.radius), not by brackets"), "{e}");
    }

    #[test]
    fn colours_parse_and_bad_ones_are_refused() {
        // A colour code is sRGB: back to its bytes through the PNG's encoding.
        let c = Color::Hex("#ff8040".into()).rgb().unwrap();
        let bytes = c.map(|v| (volume::colormap::linear_to_srgb(v) * 255.0).round() as u8);
        assert_eq!(bytes, [0xff, 0x80, 0x40]);
        assert_eq!(c[0], 1.0);
        assert!((c[1] - 0.2158).abs() < 1e-3, "{c:?}");
        assert!(Color::Hex("ff8000".into()).rgb().is_err());
        assert!(Color::Rgb([1.5, 0.0, 0.0]).rgb().is_err());
        let e = parse("background = \"#12\"\n", "s", Path::new("."), &[]).unwrap_err();
        assert!(e.contains("background"), "{e}");
    }
}
