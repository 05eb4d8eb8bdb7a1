//! Colour maps by name, for slices, overlays and colour bars.
//!
//! Every map is a table of 256 colours, entry `k` the colour at `t = k / 255`
//! ([`Colormap::srgb_table`], sRGB-encoded as the references publish them). The renderer works in
//! linear RGB and encodes sRGB when it writes a PNG, so it takes [`Colormap::linear_table`] (the
//! same colours decoded to linear light): an unlit slice then shows exactly the map's sRGB
//! colours. [`Colormap::rgb`] defines how a value between two entries is coloured; the GPU shader
//! reproduces it from the linear table.
//!
//! Sources:
//! * `viridis`, `magma`, `inferno`, `plasma`: the `colorous` crate (d3-scale-chromatic's ramps of
//!   the matplotlib maps by Smith and van der Walt), sampled with `eval_rational(k, 256)`.
//! * `hot`: matplotlib's `hot` segment data (red rises from 0.0416 to 1 over `t` in
//!   [0, 0.365079], green from 0 to 1 over [0.365079, 0.746032], blue over [0.746032, 1]).
//! * `red-yellow` and `blue-lightblue`: FSL's overlay maps, `(1, t, 0)` and `(0, t, 1)`.
//! * `cool-warm`: Kenneth Moreland's diverging map (K. Moreland, "Diverging Color Maps for
//!   Scientific Visualization", ISVC 2009), from sRGB (59, 76, 192) to (180, 4, 38) through a
//!   white-ish midpoint, interpolated in his Msh space ([`moreland_diverging`]).

use std::sync::OnceLock;

/// A named colour map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Colormap {
    /// Black to white.
    Grey,
    /// matplotlib's viridis (dark blue, green, yellow).
    Viridis,
    /// matplotlib's magma (black, purple, pale yellow).
    Magma,
    /// matplotlib's inferno (black, purple, orange, yellow).
    Inferno,
    /// matplotlib's plasma (blue, purple, orange, yellow).
    Plasma,
    /// Moreland's diverging blue-white-red map.
    CoolWarm,
    /// matplotlib's hot (black, red, yellow, white).
    Hot,
    /// FSL's red-yellow overlay map.
    RedYellow,
    /// FSL's blue-lightblue overlay map.
    BlueLightblue,
}

/// Entries in every colour table.
pub const TABLE_LEN: usize = 256;

impl Colormap {
    /// Every colour map, in the order error messages list them.
    pub const ALL: [Colormap; 9] = [
        Colormap::Grey,
        Colormap::Viridis,
        Colormap::Magma,
        Colormap::Inferno,
        Colormap::Plasma,
        Colormap::CoolWarm,
        Colormap::Hot,
        Colormap::RedYellow,
        Colormap::BlueLightblue,
    ];

    /// The name scenes and the command line use (`grey`, `viridis`, `cool-warm`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Colormap::Grey => "grey",
            Colormap::Viridis => "viridis",
            Colormap::Magma => "magma",
            Colormap::Inferno => "inferno",
            Colormap::Plasma => "plasma",
            Colormap::CoolWarm => "cool-warm",
            Colormap::Hot => "hot",
            Colormap::RedYellow => "red-yellow",
            Colormap::BlueLightblue => "blue-lightblue",
        }
    }

    /// The 256 sRGB-encoded colours of the map, components in [0, 1]; entry `k` is the colour
    /// at `t = k / 255`.
    pub fn srgb_table(self) -> Vec<[f32; 3]> {
        tables()[self as usize].srgb.clone()
    }

    /// [`Colormap::srgb_table`] decoded to linear light with the sRGB EOTF ([`srgb_to_linear`]):
    /// the table the renderer (which works in linear RGB) uploads.
    pub fn linear_table(self) -> Vec<[f32; 3]> {
        tables()[self as usize].linear.clone()
    }

    /// The linear-RGB colour at `t`. This is the definition of the map between table entries,
    /// which the GPU shader reproduces from [`Colormap::linear_table`]:
    ///
    /// * `t` is clamped to [0, 1] (NaN counts as 0);
    /// * `x = t * 255`, `i = min(floor(x), 254)`, `f = x - i`;
    /// * the result is `(1 - f) * table[i] + f * table[i + 1]`, computed in `f64`.
    ///
    /// So `rgb(k / 255)` is entry `k` (to rounding; exactly at 0 and 1) and the colour is linear
    /// in `t` between entries.
    pub fn rgb(self, t: f64) -> [f64; 3] {
        Self::lerp(&tables()[self as usize].linear, t)
    }

    /// The sRGB-encoded colour at `t`, interpolated in [`Colormap::srgb_table`] as
    /// [`Colormap::rgb`] is in the linear one: what a file's 8-bit colours (a mesh's vertex
    /// colours, which the renderer decodes) carry.
    pub fn srgb(self, t: f64) -> [f64; 3] {
        Self::lerp(&tables()[self as usize].srgb, t)
    }

    fn lerp(table: &[[f32; 3]], t: f64) -> [f64; 3] {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        let x = t * (TABLE_LEN - 1) as f64;
        let i = (x.floor() as usize).min(TABLE_LEN - 2);
        let f = x - i as f64;
        let (a, b) = (table[i], table[i + 1]);
        std::array::from_fn(|c| (1.0 - f) * a[c] as f64 + f * b[c] as f64)
    }

    /// The sRGB colour at `t = k / 255` (`k` in 0..=255), computed from the map's source.
    fn srgb_entry(self, k: usize) -> [f64; 3] {
        let t = k as f64 / (TABLE_LEN - 1) as f64;
        let from_colorous = |g: colorous::Gradient| {
            let c = g.eval_rational(k, TABLE_LEN);
            [c.r, c.g, c.b].map(|v| v as f64 / 255.0)
        };
        match self {
            Colormap::Grey => [t; 3],
            Colormap::Viridis => from_colorous(colorous::VIRIDIS),
            Colormap::Magma => from_colorous(colorous::MAGMA),
            Colormap::Inferno => from_colorous(colorous::INFERNO),
            Colormap::Plasma => from_colorous(colorous::PLASMA),
            Colormap::CoolWarm => moreland_diverging(COOL_WARM_ENDS[0], COOL_WARM_ENDS[1], t),
            Colormap::Hot => hot(t),
            Colormap::RedYellow => [1.0, t, 0.0],
            Colormap::BlueLightblue => [0.0, t, 1.0],
        }
    }
}

impl std::fmt::Display for Colormap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Colormap {
    type Err = String;

    /// Parses a map's [`Colormap::name`] (or `gray` for `grey`); the error lists the names.
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "gray" {
            return Ok(Colormap::Grey);
        }
        Colormap::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Colormap::ALL.iter().map(|m| m.name()).collect();
                format!(
                    "'{}' is not a colour map; one of {}",
                    crate::io_util::clip_text(s, 60),
                    names.join(", ")
                )
            })
    }
}

/// One map's tables, computed once.
struct Tables {
    srgb: Vec<[f32; 3]>,
    linear: Vec<[f32; 3]>,
}

fn tables() -> &'static [Tables; 9] {
    static TABLES: OnceLock<[Tables; 9]> = OnceLock::new();
    TABLES.get_or_init(|| {
        Colormap::ALL.map(|m| {
            let srgb: Vec<[f64; 3]> = (0..TABLE_LEN)
                .map(|k| m.srgb_entry(k).map(|v| v.clamp(0.0, 1.0)))
                .collect();
            Tables {
                srgb: srgb.iter().map(|c| c.map(|v| v as f32)).collect(),
                linear: srgb
                    .iter()
                    .map(|c| c.map(|v| srgb_to_linear(v) as f32))
                    .collect(),
            }
        })
    })
}

/// The sRGB EOTF (IEC 61966-2-1): an encoded component in [0, 1] to linear light.
pub fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// The inverse of [`srgb_to_linear`]: linear light in [0, 1] to an sRGB-encoded component.
pub fn linear_to_srgb(v: f64) -> f64 {
    if v <= 0.0031308 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// matplotlib's `hot` at `t` (its segment data `_hot_data`; sRGB).
fn hot(t: f64) -> [f64; 3] {
    let ramp = |lo: f64, hi: f64| ((t - lo) / (hi - lo)).clamp(0.0, 1.0);
    let r0 = 0.0416;
    [
        r0 + (1.0 - r0) * ramp(0.0, 0.365079),
        ramp(0.365079, 0.746032),
        ramp(0.746032, 1.0),
    ]
}

/// The end colours of `cool-warm` (Moreland 2009, table of the recommended map), sRGB in [0, 1].
const COOL_WARM_ENDS: [[f64; 3]; 2] = [
    [59.0 / 255.0, 76.0 / 255.0, 192.0 / 255.0],
    [180.0 / 255.0, 4.0 / 255.0, 38.0 / 255.0],
];

/// The CIE XYZ of the D65 white of linear sRGB (the row sums of [`LINEAR_TO_XYZ`]), the
/// reference white of the CIELAB conversion as in Moreland's paper.
const WHITE: [f64; 3] = [0.9505, 1.0, 1.089];

/// Linear sRGB to CIE XYZ (D65), rows X, Y, Z (IEC 61966-2-1).
const LINEAR_TO_XYZ: [[f64; 3]; 3] = [
    [0.4124, 0.3576, 0.1805],
    [0.2126, 0.7152, 0.0722],
    [0.0193, 0.1192, 0.9505],
];

fn mat_vec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    m.map(|row| row[0] * v[0] + row[1] * v[1] + row[2] * v[2])
}

/// The inverse of a 3 x 3 matrix (by cofactors; the matrices here are well conditioned).
fn mat_inverse(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let c = |r: usize, s: usize| {
        let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
        let (s1, s2) = ((s + 1) % 3, (s + 2) % 3);
        m[r1][s1] * m[r2][s2] - m[r1][s2] * m[r2][s1]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    std::array::from_fn(|i| std::array::from_fn(|j| c(j, i) / det))
}

/// sRGB (encoded, [0, 1]) to CIELAB relative to the D65 white of sRGB, XYZ (0.9505, 1, 1.089)
/// (Moreland 2009, section 4 and its appendix: sRGB to linear RGB (the sRGB EOTF) to XYZ (the
/// IEC 61966-2-1 matrix) to L*a*b*).
pub fn srgb_to_lab(srgb: [f64; 3]) -> [f64; 3] {
    let xyz = mat_vec(&LINEAR_TO_XYZ, srgb.map(srgb_to_linear));
    let f = |t: f64| {
        let d: f64 = 6.0 / 29.0;
        if t > d * d * d {
            t.cbrt()
        } else {
            t / (3.0 * d * d) + 4.0 / 29.0
        }
    };
    let [fx, fy, fz] = [0, 1, 2].map(|c| f(xyz[c] / WHITE[c]));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// The inverse of [`srgb_to_lab`]; components outside [0, 1] are clamped.
pub fn lab_to_srgb(lab: [f64; 3]) -> [f64; 3] {
    let fy = (lab[0] + 16.0) / 116.0;
    let fx = fy + lab[1] / 500.0;
    let fz = fy - lab[2] / 200.0;
    let finv = |t: f64| {
        let d: f64 = 6.0 / 29.0;
        if t > d {
            t * t * t
        } else {
            3.0 * d * d * (t - 4.0 / 29.0)
        }
    };
    let xyz = [
        finv(fx) * WHITE[0],
        finv(fy) * WHITE[1],
        finv(fz) * WHITE[2],
    ];
    let linear = mat_vec(&mat_inverse(&LINEAR_TO_XYZ), xyz);
    linear.map(|v| linear_to_srgb(v.clamp(0.0, 1.0)).clamp(0.0, 1.0))
}

/// CIELAB to Moreland's Msh: magnitude `M = |(L, a, b)|`, saturation `s = acos(L / M)`, hue
/// `h = atan2(b, a)` (Moreland 2009, equation 1).
pub fn lab_to_msh(lab: [f64; 3]) -> [f64; 3] {
    let m = (lab[0] * lab[0] + lab[1] * lab[1] + lab[2] * lab[2]).sqrt();
    let s = if m > 0.0 {
        (lab[0] / m).clamp(-1.0, 1.0).acos()
    } else {
        0.0
    };
    [m, s, lab[2].atan2(lab[1])]
}

/// Msh to CIELAB: `L = M cos s`, `a = M sin s cos h`, `b = M sin s sin h` (Moreland 2009,
/// equation 2).
pub fn msh_to_lab(msh: [f64; 3]) -> [f64; 3] {
    let [m, s, h] = msh;
    [m * s.cos(), m * s.sin() * h.cos(), m * s.sin() * h.sin()]
}

/// Moreland's hue adjustment (2009, section 5, `AdjustHue`): the hue to give an unsaturated
/// colour of magnitude `m_unsat` interpolated towards the saturated colour `msh`, spinning the
/// hue away from it so that the interpolation does not pass through a bend.
pub fn adjust_hue(msh: [f64; 3], m_unsat: f64) -> f64 {
    let [m, s, h] = msh;
    if m >= m_unsat {
        return h;
    }
    let spin = s * (m_unsat * m_unsat - m * m).sqrt() / (m * s.sin());
    if h > -std::f64::consts::FRAC_PI_3 {
        h + spin
    } else {
        h - spin
    }
}

/// Moreland's diverging interpolation (2009, section 5, `InterpolateColor`) between the sRGB
/// colours `c1` (at `t = 0`) and `c2` (at `t = 1`): when both are saturated (`s > 0.05`) and
/// their hues differ by more than pi/3, the map passes through an unsaturated midpoint of
/// magnitude `max(M1, M2, 88)` at `t = 1/2`; an unsaturated end takes its hue from
/// [`adjust_hue`]; then M, s and h are interpolated linearly. Returns sRGB clamped to [0, 1].
pub fn moreland_diverging(c1: [f64; 3], c2: [f64; 3], t: f64) -> [f64; 3] {
    let mut a = lab_to_msh(srgb_to_lab(c1));
    let mut b = lab_to_msh(srgb_to_lab(c2));
    let mut t = t.clamp(0.0, 1.0);
    if a[1] > 0.05 && b[1] > 0.05 && hue_difference(a[2], b[2]) > std::f64::consts::FRAC_PI_3 {
        let mid = a[0].max(b[0]).max(88.0);
        if t < 0.5 {
            b = [mid, 0.0, 0.0];
            t *= 2.0;
        } else {
            a = [mid, 0.0, 0.0];
            t = 2.0 * t - 1.0;
        }
    }
    if a[1] < 0.05 && b[1] > 0.05 {
        a[2] = adjust_hue(b, a[0]);
    } else if b[1] < 0.05 && a[1] > 0.05 {
        b[2] = adjust_hue(a, b[0]);
    }
    let msh: [f64; 3] = std::array::from_fn(|c| (1.0 - t) * a[c] + t * b[c]);
    lab_to_srgb(msh_to_lab(msh))
}

/// The angle between two hues in radians, in [0, pi] (the paper's `RadDiff`).
fn hue_difference(h1: f64, h2: f64) -> f64 {
    let d = (h1 - h2).abs() % std::f64::consts::TAU;
    d.min(std::f64::consts::TAU - d)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn luminance(c: [f32; 3]) -> f64 {
        0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
    }

    fn hex(s: &str) -> [f32; 3] {
        let v = u32::from_str_radix(s, 16).unwrap();
        [v >> 16, (v >> 8) & 255, v & 255].map(|c| c as f32 / 255.0)
    }

    fn near(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
        (0..3).all(|c| (a[c] - b[c]).abs() <= tol)
    }

    #[test]
    fn names_round_trip() {
        for m in Colormap::ALL {
            assert_eq!(m.name().parse::<Colormap>(), Ok(m));
            assert_eq!(m.to_string(), m.name());
        }
        assert_eq!("gray".parse::<Colormap>(), Ok(Colormap::Grey));
        let names: Vec<_> = Colormap::ALL.iter().map(|m| m.name()).collect();
        assert_eq!(
            names,
            [
                "grey",
                "viridis",
                "magma",
                "inferno",
                "plasma",
                "cool-warm",
                "hot",
                "red-yellow",
                "blue-lightblue"
            ]
        );
    }

    #[test]
    fn unknown_name_lists_the_maps() {
        let e = "jet".parse::<Colormap>().unwrap_err();
        assert!(
            e.starts_with("'jet' is not a colour map; one of grey, viridis, magma"),
            "{e}"
        );
        assert!(e.ends_with("red-yellow, blue-lightblue"), "{e}");
        assert!("Viridis".parse::<Colormap>().is_err());
        assert!("".parse::<Colormap>().is_err());
    }

    #[test]
    fn tables_have_256_entries_in_range() {
        for m in Colormap::ALL {
            for table in [m.srgb_table(), m.linear_table()] {
                assert_eq!(table.len(), TABLE_LEN, "{m}");
                assert!(
                    table.iter().flatten().all(|v| (0.0..=1.0).contains(v)),
                    "{m}"
                );
            }
        }
    }

    #[test]
    fn sequential_maps_rise_in_luminance() {
        use Colormap::*;
        for m in [
            Grey,
            Viridis,
            Magma,
            Inferno,
            Plasma,
            Hot,
            RedYellow,
            BlueLightblue,
        ] {
            // colorous gives 8-bit colours (truncated): viridis's luminance dips by up to 3e-4
            // at two entries, less than one 8-bit step of green there (~2e-3). So: no dip of
            // more than 5e-4 from one entry to the next, and a strict rise over every 3 entries.
            let table = m.linear_table();
            for k in 1..TABLE_LEN {
                let (a, b) = (luminance(table[k - 1]), luminance(table[k]));
                assert!(
                    b >= a - 5e-4,
                    "{m}: luminance falls from entry {} ({a}) to {k} ({b})",
                    k - 1
                );
                if k >= 3 {
                    assert!(b > luminance(table[k - 3]), "{m}: entries {}..={k}", k - 3);
                }
            }
            assert!(luminance(table[255]) > luminance(table[0]) + 0.5, "{m}");
        }
    }

    #[test]
    fn known_entries() {
        let v = Colormap::Viridis.srgb_table();
        assert!(near(v[0], hex("440154"), 1.5 / 255.0), "{:?}", v[0]);
        assert!(near(v[255], hex("fde725"), 1.5 / 255.0), "{:?}", v[255]);
        let g = Colormap::Grey.srgb_table();
        assert_eq!(g[0], [0.0; 3]);
        assert_eq!(g[51], [0.2; 3]);
        assert_eq!(g[255], [1.0; 3]);
        let h = Colormap::Hot.srgb_table();
        assert!(near(h[0], [0.0416, 0.0, 0.0], 1e-6));
        assert_eq!(h[255], [1.0; 3]);
        assert_eq!(Colormap::RedYellow.srgb_table()[0], [1.0, 0.0, 0.0]);
        assert_eq!(Colormap::RedYellow.srgb_table()[255], [1.0, 1.0, 0.0]);
        assert_eq!(Colormap::BlueLightblue.srgb_table()[0], [0.0, 0.0, 1.0]);
        assert_eq!(Colormap::BlueLightblue.srgb_table()[255], [0.0, 1.0, 1.0]);
    }

    #[test]
    fn linear_table_decodes_the_srgb_table() {
        for m in Colormap::ALL {
            for (s, l) in m.srgb_table().iter().zip(m.linear_table()) {
                for c in 0..3 {
                    let back = linear_to_srgb(l[c] as f64);
                    assert!((back - s[c] as f64).abs() < 1e-5, "{m}: {s:?} vs {l:?}");
                }
            }
        }
        // Mid grey: sRGB 0.5 is about 21.4 % linear light.
        let mid = Colormap::Grey.rgb(0.5)[0];
        assert!((mid - 0.2140).abs() < 2e-3, "{mid}");
    }

    #[test]
    fn cool_warm_ends_and_midpoint() {
        let table = Colormap::CoolWarm.srgb_table();
        let ends = COOL_WARM_ENDS.map(|c| c.map(|v| v as f32));
        assert!(near(table[0], ends[0], 1e-4), "{:?}", table[0]);
        assert!(near(table[255], ends[1], 1e-4), "{:?}", table[255]);
        let grey = [221.0 / 255.0; 3];
        let mid = moreland_diverging(COOL_WARM_ENDS[0], COOL_WARM_ENDS[1], 0.5).map(|v| v as f32);
        assert!(near(mid, grey, 2.0 / 255.0), "{mid:?}");
        // The table's two middle entries straddle it.
        assert!(near(table[127], grey, 4.0 / 255.0), "{:?}", table[127]);
        assert!(near(table[128], grey, 4.0 / 255.0), "{:?}", table[128]);
        // Cool half blue-ish, warm half red-ish.
        assert!(table[64][2] > table[64][0]);
        assert!(table[192][0] > table[192][2]);
    }

    #[test]
    fn lab_and_msh_round_trip() {
        for c in [
            [0.2, 0.5, 0.9],
            [0.9, 0.1, 0.3],
            [0.5, 0.5, 0.5],
            COOL_WARM_ENDS[1],
        ] {
            let back = lab_to_srgb(msh_to_lab(lab_to_msh(srgb_to_lab(c))));
            for k in 0..3 {
                assert!((back[k] - c[k]).abs() < 1e-9, "{c:?} -> {back:?}");
            }
        }
        let white = srgb_to_lab([1.0; 3]);
        assert!((white[0] - 100.0).abs() < 1e-9 && white[1].abs() < 1e-9 && white[2].abs() < 1e-9);
    }

    #[test]
    fn rgb_ends_are_the_table_ends() {
        for m in Colormap::ALL {
            let table = m.linear_table();
            let as64 = |c: [f32; 3]| c.map(|v| v as f64);
            assert_eq!(m.rgb(0.0), as64(table[0]), "{m}");
            assert_eq!(m.rgb(1.0), as64(table[255]), "{m}");
            assert_eq!(m.rgb(-3.0), as64(table[0]), "{m}");
            assert_eq!(m.rgb(7.0), as64(table[255]), "{m}");
            assert_eq!(m.rgb(f64::NAN), as64(table[0]), "{m}");
            assert_eq!(m.rgb(f64::INFINITY), as64(table[255]), "{m}");
        }
    }

    #[test]
    fn rgb_interpolates_linearly_between_entries() {
        for m in Colormap::ALL {
            let table = m.linear_table();
            for k in [0usize, 17, 127, 200, 254] {
                for f in [0.0, 0.25, 0.5, 0.9] {
                    let got = m.rgb((k as f64 + f) / 255.0);
                    for c in 0..3 {
                        let want = (1.0 - f) * table[k][c] as f64 + f * table[k + 1][c] as f64;
                        assert!((got[c] - want).abs() < 1e-12, "{m} {k} {f}: {got:?}");
                    }
                }
            }
        }
    }
}
