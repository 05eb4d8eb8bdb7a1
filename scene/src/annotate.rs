//! Annotations over a rendered image (`[annotate]`): a title, orientation labels, a scale bar
//! and a colour bar, drawn on the CPU into the frame's linear RGBA pixels before it is written,
//! with the bundled DejaVu Sans ([`FONT`]). Sizes follow the image: the text height is
//! `clamp(min(width, height) / 28, 9, 96)` pixels and every margin is 0.6 of it, so a figure at
//! 4x the size has the same layout at 4x the scale.
//!
//! - Orientation labels: for each edge, the world axis direction (+x R, -x L, +y A, -y P, +z S,
//!   -z I in RAS+; `+X` ... `-Z` for data in the file's own frame) whose projection reaches
//!   furthest towards it (a unit step from the camera's target, projected; so of two axes that
//!   both point up the screen the less foreshortened one wins).
//! - Scale bar: at the bottom left, `length x (pixels per world unit at the camera's target)`
//!   pixels long, with its length and units above it.
//! - Colour bar: at the bottom right, a horizontal ramp of the colouring (the range's low end at
//!   the left), its range below and above it its label, units and colour map's name
//!   (`speed [m/s], viridis`).

use crate::spec::{AnnotateSpec, ScaleBarSpec};
use ab_glyph::{Font, FontRef, PxScale, ScaleFont};
use glam::DVec3;
use occlusion::camera::Camera;

/// DejaVu Sans (Bitstream Vera license, `scene/assets/`).
pub const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// A colouring to draw as a colour bar: its range and its colours sampled evenly over it.
#[derive(Clone, Debug, PartialEq)]
pub struct ColorBar {
    pub label: String,
    /// The colour map's name (`viridis`, `transfer function`), written after the label.
    pub map: String,
    pub range: [f64; 2],
    /// Linear RGB from the range's low end to its high end.
    pub colors: Vec<[f32; 3]>,
}

/// What the annotations need beyond their keys.
pub struct Context<'a> {
    pub camera: &'a Camera,
    /// Whether world coordinates are RAS+ (anatomical labels and `mm`).
    pub ras: bool,
    pub background: [f32; 3],
    pub colorbar: Option<&'a ColorBar>,
}

/// A pixel rectangle `[x0, y0, x1, y1)`.
pub type Rect = [f32; 4];

/// Where each annotation was drawn (what the layout tests check).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Placed {
    pub text_px: f32,
    pub title: Option<Rect>,
    /// Right, left, top, bottom edge labels with their boxes.
    pub labels: Vec<(String, Rect)>,
    /// The bar, its length in pixels and in world units.
    pub scale_bar: Option<(Rect, f64, f64)>,
    /// The scale bar's length label: its text box.
    pub scale_label: Option<Rect>,
    pub colorbar: Option<Rect>,
    /// The colour bar's end labels (low, high): their text boxes.
    pub colorbar_ends: Vec<Rect>,
}

/// The text height of an image of `w` x `h` pixels.
pub fn text_px(w: usize, h: usize) -> f32 {
    (w.min(h) as f32 / 28.0).clamp(9.0, 96.0)
}

/// 1, 2 or 5 times a power of ten, the largest not above `x` (`x` > 0).
pub fn nice_length(x: f64) -> f64 {
    let p = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * p)
        .find(|&v| v <= x * (1.0 + 1e-9))
        .unwrap_or(p)
}

/// A number in at most 4 significant digits, without trailing zeros: plainly from 1e-4 up to
/// 1e4, in scientific notation outside (`-2.278e10`: a field's range in pascals stays short
/// enough for the colour bar's two ends).
pub fn format_number(v: f64) -> String {
    format_digits(v, 4)
}

/// [`format_number`] with at most `sig` significant digits (1 to 17).
pub fn format_digits(v: f64, sig: usize) -> String {
    let sig = sig.clamp(1, 17);
    if v == 0.0 {
        // -0 too.
        return "0".into();
    }
    if !v.is_finite() {
        return format!("{v}");
    }
    if !(1e-4..1e4).contains(&v.abs()) {
        let s = format!("{v:.*e}", sig - 1);
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = if mantissa.contains('.') {
            mantissa.trim_end_matches('0').trim_end_matches('.')
        } else {
            mantissa
        };
        return format!("{mantissa}e{exponent}");
    }
    let digits = (sig as i32 - 1 - v.abs().log10().floor() as i32).clamp(0, 20) as usize;
    let s = format!("{v:.digits$}");
    if s.trim_start_matches('-').len() > 4 && !s.contains('.') {
        // Rounded up to 1e4 (9999.6): five digits; as the numbers from 1e4 up are written.
        return format_digits(s.parse::<f64>().unwrap_or(v).signum() * 1e4, sig);
    }
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" {
        "0".into()
    } else {
        s
    }
}

/// The two ends of a range as [`format_number`] writes them, with as many more significant
/// digits as it takes (up to 9) for the labels to give the range's width within a tenth: a
/// narrow window on offset data, `[9999.5, 10000.5]`, is not labelled "1e4" at both ends.
pub fn format_ends(range: [f64; 2]) -> (String, String) {
    let width = range[1] - range[0];
    let mut sig = 4;
    loop {
        let (lo, hi) = (format_digits(range[0], sig), format_digits(range[1], sig));
        let shown = hi.parse::<f64>().unwrap_or(f64::NAN) - lo.parse::<f64>().unwrap_or(f64::NAN);
        let close = (shown - width).abs() <= 0.1 * width.abs();
        if close || !width.is_finite() || width == 0.0 || sig >= 9 {
            return (lo, hi);
        }
        sig += 1;
    }
}

/// The label of a world direction: R/L, A/P, S/I in RAS+ (`ras`), else +X/-X, +Y/-Y, +Z/-Z.
pub fn axis_label(axis: usize, positive: bool, ras: bool) -> String {
    if ras {
        ["LR", "PA", "IS"][axis][positive as usize..=positive as usize].to_string()
    } else {
        format!(
            "{}{}",
            if positive { '+' } else { '-' },
            ['X', 'Y', 'Z'][axis]
        )
    }
}

/// The labels of the right, left, top and bottom edges for `camera` on a `w` x `h` image.
pub fn orientation_labels(camera: &Camera, w: usize, h: usize, ras: bool) -> [String; 4] {
    let t = camera.target;
    // A millionth of the distance: the projection's derivative at the target (with a
    // hundredth, perspective made of two axes at 45 degrees the one towards the eye longer by
    // 1.4%, and it named the edge alone).
    let step = (camera.eye - t).length().max(1e-9) * 1e-6;
    let p0 = camera.to_pixel(t, w, h);
    // Screen direction (pixels, y down) of each of the six world directions.
    let dirs: Vec<(String, f64, f64)> = (0..6)
        .filter_map(|k| {
            let (axis, positive) = (k / 2, k % 2 == 1);
            let mut d = DVec3::ZERO;
            d[axis] = if positive { step } else { -step };
            let (p0, p1) = (p0?, camera.to_pixel(t + d, w, h)?);
            // Not normalised: of two axes that both point up the screen, the one less
            // foreshortened names the edge.
            Some((axis_label(axis, positive, ras), p1.0 - p0.0, p1.1 - p0.1))
        })
        .collect();
    // The direction pointing most towards the edge; where two or three tie (a camera at
    // exactly 45 degrees between two axes), all of them in axis order ("RA", "+X+Y"): which
    // one won was the rounding's choice, and could flip between two such views.
    let best = |score: &dyn Fn(f64, f64) -> f64| {
        let top = dirs
            .iter()
            .map(|d| score(d.1, d.2))
            .fold(f64::NEG_INFINITY, f64::max);
        let tie = 1e-4 * top.abs().max(1e-300);
        dirs.iter()
            .filter(|d| score(d.1, d.2) >= top - tie)
            .map(|d| d.0.as_str())
            .collect::<String>()
    };
    [
        best(&|x, _| x),
        best(&|x, _| -x),
        best(&|_, y| -y),
        best(&|_, y| y),
    ]
}

/// Pixels per world unit at the camera's target, along the screen's horizontal.
pub fn pixels_per_unit(camera: &Camera, w: usize, h: usize) -> Option<f64> {
    let right = camera.forward().cross(camera.up).normalize_or_zero();
    let t = camera.target;
    let step = (camera.eye - t).length().max(1e-9) * 0.01;
    let (a, b) = (
        camera.to_pixel(t, w, h)?,
        camera.to_pixel(t + right * step, w, h)?,
    );
    let d = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt() / step;
    (d.is_finite() && d > 0.0).then_some(d)
}

struct Canvas<'a> {
    img: &'a mut [[f32; 4]],
    w: usize,
    h: usize,
}

impl Canvas<'_> {
    /// Covers pixel (x, y) by `a` of colour `c` (linear), mixed in sRGB-encoded values, as
    /// text is drawn on screens and paper: a glyph's edge pixel half covered is half-way in
    /// lightness, not in light (mixed in linear light, black text on white at coverage 0.5
    /// was 188 of 255: small text came out grey, and a 1-bit image, cut at half lightness,
    /// lost most of its labels).
    fn blend(&mut self, x: i64, y: i64, c: [f32; 3], a: f32) {
        if x < 0 || y < 0 || x >= self.w as i64 || y >= self.h as i64 || a <= 0.0 {
            return;
        }
        let p = &mut self.img[y as usize * self.w + x as usize];
        let a = a.min(1.0) as f64;
        use volume::colormap::{linear_to_srgb, srgb_to_linear};
        for k in 0..3 {
            let (under, over) = (linear_to_srgb(p[k] as f64), linear_to_srgb(c[k] as f64));
            p[k] = srgb_to_linear(under * (1.0 - a) + over * a) as f32;
        }
        p[3] = (p[3] as f64 * (1.0 - a) + a) as f32;
    }

    fn fill(&mut self, r: Rect, c: [f32; 3]) {
        // Clamped to the image: a bar may be longer than the image is wide.
        let (w, h) = (self.w as f32, self.h as f32);
        let (x0, x1) = (
            r[0].clamp(0.0, w).round() as i64,
            r[2].clamp(0.0, w).round() as i64,
        );
        let (y0, y1) = (
            r[1].clamp(0.0, h).round() as i64,
            r[3].clamp(0.0, h).round() as i64,
        );
        for y in y0..y1 {
            for x in x0..x1 {
                self.blend(x, y, c, 1.0);
            }
        }
    }
}

/// The characters of `text` the bundled font has no glyph for (drawn as empty boxes), each
/// once, in order; spaces always have one.
pub fn missing_glyphs(text: &str) -> Vec<char> {
    let Ok(font) = FontRef::try_from_slice(FONT) else {
        return vec![];
    };
    let mut out: Vec<char> = vec![];
    for ch in text.chars() {
        if font.glyph_id(ch).0 == 0 && !ch.is_whitespace() && !out.contains(&ch) {
            out.push(ch);
        }
    }
    out
}

/// `label` cut to `avail` pixels wide at `px`, ending in an ellipsis when cut; its width.
fn fit(font: &FontRef, px: f32, label: &str, avail: f32) -> (String, f32) {
    let mut label = label.to_string();
    let (mut lw, _) = extent(font, px, &label);
    if lw > avail {
        let mut chars: Vec<char> = label.chars().collect();
        while chars.len() > 1 && lw > avail {
            chars.pop();
            label = chars.iter().collect::<String>() + "\u{2026}";
            lw = extent(font, px, &label).0;
        }
    }
    (label, lw)
}

/// Width and height of `text` at `px` pixels.
fn extent(font: &FontRef, px: f32, text: &str) -> (f32, f32) {
    let f = font.as_scaled(PxScale::from(px));
    let mut x = 0.0;
    let mut prev = None;
    for ch in text.chars() {
        let g = f.glyph_id(ch);
        if let Some(p) = prev {
            x += f.kern(p, g);
        }
        x += f.h_advance(g);
        prev = Some(g);
    }
    (x, f.ascent() - f.descent())
}

/// Draws `text` with its box's top left at (`x`, `y`) in `fg`, over a one-pixel halo of `halo`
/// so that it reads over any image; returns its box.
/// The font and the colours text is drawn in.
struct Pen<'a> {
    font: FontRef<'a>,
    fg: [f32; 3],
    halo: [f32; 3],
}

fn text(cv: &mut Canvas, pen: &Pen, px: f32, s: &str, x: f32, y: f32) -> Rect {
    let (font, fg, halo) = (&pen.font, pen.fg, pen.halo);
    let (tw, th) = extent(font, px, s);
    let (bw, bh) = (tw.ceil() as usize + 4, th.ceil() as usize + 4);
    let mut mask = vec![0f32; bw * bh];
    let f = font.as_scaled(PxScale::from(px));
    let mut pen = 2.0f32;
    let mut prev = None;
    for ch in s.chars() {
        let id = f.glyph_id(ch);
        if let Some(p) = prev {
            pen += f.kern(p, id);
        }
        let g =
            id.with_scale_and_position(PxScale::from(px), ab_glyph::point(pen, 2.0 + f.ascent()));
        if let Some(o) = font.outline_glyph(g) {
            let b = o.px_bounds();
            o.draw(|gx, gy, c| {
                let (mx, my) = (b.min.x as i64 + gx as i64, b.min.y as i64 + gy as i64);
                if mx >= 0 && my >= 0 && (mx as usize) < bw && (my as usize) < bh {
                    let m = &mut mask[my as usize * bw + mx as usize];
                    *m = m.max(c);
                }
            });
        }
        pen += f.h_advance(id);
        prev = Some(id);
    }
    let (ox, oy) = (x.round() as i64 - 2, y.round() as i64 - 2);
    let at = |mx: i64, my: i64| -> f32 {
        if mx < 0 || my < 0 || mx >= bw as i64 || my >= bh as i64 {
            0.0
        } else {
            mask[my as usize * bw + mx as usize]
        }
    };
    for my in -1..=bh as i64 {
        for mx in -1..=bw as i64 {
            let mut d = 0f32;
            for (dx, dy) in [
                (-1, 0),
                (1, 0),
                (0, -1),
                (0, 1),
                (-1, -1),
                (1, 1),
                (-1, 1),
                (1, -1),
            ] {
                d = d.max(at(mx + dx, my + dy));
            }
            cv.blend(ox + mx, oy + my, halo, d * 0.85);
        }
    }
    for my in 0..bh as i64 {
        for mx in 0..bw as i64 {
            cv.blend(ox + mx, oy + my, fg, at(mx, my));
        }
    }
    [x, y, x + tw, y + th]
}

/// The colour of text and marks: the spec's, else black over light backgrounds and white over
/// dark ones; and the halo's, the other of the two.
fn colors(spec: &AnnotateSpec, background: [f32; 3]) -> Result<([f32; 3], [f32; 3]), String> {
    let lum = 0.2126 * background[0] + 0.7152 * background[1] + 0.0722 * background[2];
    let auto = if lum > 0.25 { [0.0; 3] } else { [1.0; 3] };
    let fg = match &spec.color {
        Some(c) => c
            .rgb()
            .map_err(|e| format!("scene key annotate.color: {e}"))?
            .map(|v| v as f32),
        None => auto,
    };
    let flum = 0.2126 * fg[0] + 0.7152 * fg[1] + 0.0722 * fg[2];
    let halo = if flum > 0.25 { [0.0; 3] } else { [1.0; 3] };
    Ok((fg, halo))
}

/// Draws the annotations of `spec` into `img` (`w` x `h` linear RGBA, rows top to bottom);
/// returns where they went.
pub fn draw(
    img: &mut [[f32; 4]],
    w: usize,
    h: usize,
    spec: &AnnotateSpec,
    ctx: &Context,
) -> Result<Placed, String> {
    let mut placed = Placed::default();
    if spec.is_empty() || w == 0 || h == 0 {
        return Ok(placed);
    }
    let font = FontRef::try_from_slice(FONT).map_err(|e| format!("the bundled font: {e}"))?;
    let (fg, halo) = colors(spec, ctx.background)?;
    let pen = Pen {
        font: font.clone(),
        fg,
        halo,
    };
    let px = text_px(w, h);
    let margin = 0.6 * px;
    placed.text_px = px;
    let mut cv = Canvas { img, w, h };
    let (wf, hf) = (w as f32, h as f32);
    if let Some(t) = spec.title.as_deref().filter(|t| !t.is_empty()) {
        // Centred; a title wider than the image is cut, ending in an ellipsis.
        let tp = px * 1.4;
        let (t, tw) = fit(&font, tp, t, (wf - 2.0 * margin).max(tp));
        placed.title = Some(text(
            &mut cv,
            &pen,
            tp,
            &t,
            ((wf - tw) * 0.5).max(margin),
            margin,
        ));
    }
    if spec.orientation {
        let [r, l, t, b] = orientation_labels(ctx.camera, w, h, ctx.ras);
        let e = |s: &str| extent(&font, px, s);
        let spots = [
            (r.clone(), wf - margin - e(&r).0, (hf - e(&r).1) * 0.5),
            (l.clone(), margin, (hf - e(&l).1) * 0.5),
            (
                t.clone(),
                (wf - e(&t).0) * 0.5,
                margin + placed.title.map_or(0.0, |r| r[3]),
            ),
            (b.clone(), (wf - e(&b).0) * 0.5, hf - margin - e(&b).1),
        ];
        for (s, x, y) in spots {
            let r = text(&mut cv, &pen, px, &s, x, y);
            placed.labels.push((s, r));
        }
    }
    if let Some(sb) = &spec.scale_bar {
        let ppu = pixels_per_unit(ctx.camera, w, h)
            .ok_or("annotate.scale_bar: the camera's target is not on screen")?;
        let world = match sb {
            ScaleBarSpec::Length(l) => *l,
            ScaleBarSpec::Word(_) => nice_length(wf as f64 * 0.2 / ppu),
        };
        // Whole pixels, the nearest to the length (the bar's ends on pixel edges).
        let len = (world * ppu).round();
        if len < 1.0 {
            return Err(format!(
                "annotate.scale_bar: {} is {:.2} pixels at this camera (below one pixel, no bar \
                 to draw); give a longer length or \"auto\"",
                format_number(world),
                world * ppu
            ));
        }
        let units = spec
            .units
            .clone()
            .unwrap_or_else(|| match (ctx.ras, world == 1.0) {
                (true, _) => "mm".into(),
                // "1 unit", not "1 units".
                (false, true) => "unit".into(),
                (false, false) => "units".into(),
            });
        let thick = (px * 0.3).max(2.0);
        let (x0, y1) = (margin.round(), hf - margin);
        let bar = [x0, y1 - thick, x0 + len as f32, y1];
        let label = format!("{} {units}", format_number(world));
        let (lw, lh) = extent(&font, px, &label);
        // The halo first, then the bar, so the bar reads over any image.
        cv.fill(
            [bar[0] - 1.0, bar[1] - 1.0, bar[2] + 1.0, bar[3] + 1.0],
            halo,
        );
        cv.fill(bar, fg);
        placed.scale_label = Some(text(
            &mut cv,
            &pen,
            px,
            &label,
            (x0 + (len as f32 - lw).max(0.0) * 0.5).min((wf - margin - lw).max(x0)),
            bar[1] - lh - 0.2 * px,
        ));
        placed.scale_bar = Some((bar, len, world));
    }
    if let Some(src) = &spec.colorbar {
        let cb = ctx
            .colorbar
            .ok_or_else(|| format!("annotate.colorbar: '{src}' has no colouring to show"))?;
        // 0.3 of the width, wider where its end labels would not fit under it a text height
        // apart (on a thumbnail "1.401e-44" and "0.005667" ran together into one number).
        let (lo, hi) = format_ends(cb.range);
        let ends = extent(&font, px, &lo).0 + extent(&font, px, &hi).0 + px;
        let bw = (wf * 0.3).max(ends).min(wf - 2.0 * margin).round();
        let bh = (px * 0.8).round().max(4.0);
        let x1 = wf - margin;
        let x0 = x1 - bw;
        let mut y1 = hf - margin - px * 1.25;
        // A bar widened over what the bottom row holds (a thumbnail, long end labels) goes
        // above it, its end labels clear: the scale bar and its length label, the bottom
        // orientation label ("P" ran into "0.0001234").
        let bottom_label = spec
            .orientation
            .then(|| placed.labels.get(3).map(|l| l.1))
            .flatten();
        let row = [
            placed.scale_bar.map(|s| s.0),
            placed.scale_label,
            bottom_label,
        ];
        let top = row
            .into_iter()
            .flatten()
            .filter(|r| r[2] + 0.5 * px > x0 - 2.0 && r[0] - 0.5 * px < x1 + 2.0)
            .map(|r| r[1])
            .fold(f32::INFINITY, f32::min);
        if top.is_finite() {
            y1 -= hf - top + 0.2 * px;
        }
        let y0 = y1 - bh;
        cv.fill([x0 - 2.0, y0 - 2.0, x1 + 2.0, y1 + 2.0], halo);
        cv.fill([x0 - 1.0, y0 - 1.0, x1 + 1.0, y1 + 1.0], fg);
        let n = cb.colors.len().max(1);
        for x in x0 as i64..x1 as i64 {
            let t = (x as f32 - x0 + 0.5) / bw;
            let c = cb.colors[((t * n as f32) as usize).min(n - 1)];
            for y in y0 as i64..y1 as i64 {
                cv.blend(x, y, c, 1.0);
            }
        }
        // Below the bar's frame and its halo (2 pixels), not touching them.
        let below = y1 + 2.0 + 0.2 * px;
        let (hw, _) = extent(&font, px, &hi);
        placed.colorbar_ends = vec![
            text(&mut cv, &pen, px, &lo, x0, below),
            text(&mut cv, &pen, px, &hi, x1 - hw, below),
        ];
        let mut label = spec
            .colorbar_label
            .clone()
            .unwrap_or_else(|| cb.label.clone());
        if let Some(u) = spec.colorbar_units.as_deref().filter(|u| !u.is_empty()) {
            label = format!("{label} [{u}]");
        }
        if !cb.map.is_empty() {
            label = if label.is_empty() {
                cb.map.clone()
            } else {
                format!("{label}, {}", cb.map)
            };
        }
        if !label.is_empty() {
            // Centred over the bar, moved left to stay inside the image; a label wider than
            // the image is cut, ending in an ellipsis.
            let avail = (wf - 2.0 * margin).max(px);
            let (label, lw) = fit(&font, px, &label, avail);
            let lh = extent(&font, px, &label).1;
            let x = (x0 + (bw - lw) * 0.5).min(wf - margin - lw).max(margin);
            text(&mut cv, &pen, px, &label, x, y0 - lh - 0.2 * px);
        }
        placed.colorbar = Some([x0, y0, x1, y1]);
    }
    Ok(placed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use occlusion::camera::Projection;

    /// A viridis colour bar labelled `label` over `range`.
    fn viridis_bar(label: &str, range: [f64; 2]) -> ColorBar {
        ColorBar {
            label: label.into(),
            map: "viridis".into(),
            range,
            colors: (0..64)
                .map(|k| tubes::tube_mesh::colormap(k as f64 / 63.0))
                .collect(),
        }
    }

    /// Coverage mixes sRGB-encoded values: black at half coverage over white is half-way in
    /// lightness (128 of 255, 188 when mixed in linear light), so a 1-bit image, cut at half
    /// lightness, keeps a glyph's pixels that are at least half covered.
    #[test]
    fn text_coverage_mixes_in_srgb_lightness() {
        let mut img = vec![[1.0f32, 1.0, 1.0, 1.0]; 4];
        let mut cv = Canvas {
            img: &mut img,
            w: 2,
            h: 2,
        };
        for (x, a) in [(0, 0.5f32), (1, 0.45)] {
            cv.blend(x, 0, [0.0; 3], a);
        }
        cv.blend(0, 1, [0.0; 3], 0.55);
        let v = |p: [f32; 4]| crate::image_io::srgb8(p[0]);
        assert!((127..=128).contains(&v(img[0])), "{}", v(img[0]));
        assert_eq!(
            crate::image_io::one_bit([img[2][0]; 3]),
            0,
            "55% covered: black"
        );
        assert_eq!(
            crate::image_io::one_bit([img[1][0]; 3]),
            255,
            "45% covered: white"
        );
    }

    fn cam(eye: DVec3, up: DVec3) -> Camera {
        Camera::look_at(
            eye,
            DVec3::ZERO,
            up,
            Projection::Perspective { fov_y_deg: 30.0 },
            [DVec3::splat(-50.0), DVec3::splat(50.0)],
        )
        .unwrap()
    }

    #[test]
    fn orientation_labels_name_the_direction_each_edge_faces() {
        // Looking down at 50 degrees from the front: anterior is further up the screen than
        // superior.
        let e = 50f64.to_radians();
        let oblique = cam(DVec3::new(0.0, 400.0 * e.cos(), 400.0 * e.sin()), DVec3::Z);
        assert_eq!(
            orientation_labels(&oblique, 200, 100, true)[2..],
            ["P", "A"].map(String::from)
        );
        // Seen from the front (eye anterior, +y), head up: the subject's right (+x) is on the
        // viewer's left, as when facing a person.
        let front = cam(DVec3::new(0.0, 400.0, 0.0), DVec3::Z);
        assert_eq!(
            orientation_labels(&front, 200, 100, true),
            ["L", "R", "S", "I"].map(String::from)
        );
        // From above (eye superior), anterior up on screen.
        let top = cam(DVec3::new(0.0, 0.0, 400.0), DVec3::Y);
        assert_eq!(
            orientation_labels(&top, 100, 100, true),
            ["R", "L", "A", "P"].map(String::from)
        );
        // From the right side (eye at +x).
        let side = cam(DVec3::new(400.0, 0.0, 0.0), DVec3::Z);
        assert_eq!(
            orientation_labels(&side, 100, 100, true),
            ["A", "P", "S", "I"].map(String::from)
        );
        assert_eq!(
            orientation_labels(&side, 100, 100, false),
            ["+Y", "-Y", "+Z", "-Z"].map(String::from)
        );
        // Exactly between the right side and the front (eye at +x +y, azimuth 45 degrees): the
        // two axes tie on the left and right edges and both are named, in axis order, the
        // same for the eye a hair either way of the diagonal (one of the two won by the
        // rounding before).
        for dx in [0.0, 1e-12, -1e-12] {
            let diagonal = cam(DVec3::new(400.0 + dx, 400.0, 0.0), DVec3::Z);
            assert_eq!(
                orientation_labels(&diagonal, 100, 100, true),
                ["LA", "RP", "S", "I"].map(String::from)
            );
        }
        // Off the diagonal by a degree, one axis names each edge again.
        let a = 46f64.to_radians();
        let near = cam(DVec3::new(400.0 * a.cos(), 400.0 * a.sin(), 0.0), DVec3::Z);
        assert_eq!(
            orientation_labels(&near, 100, 100, true)[2..],
            ["S", "I"].map(String::from)
        );
        assert_eq!(orientation_labels(&near, 100, 100, true)[0].len(), 1);
    }

    #[test]
    fn a_scale_bar_longer_than_the_image_is_cut_at_its_edge() {
        let camera = cam(DVec3::new(0.0, 0.0, 400.0), DVec3::Y);
        let (w, h) = (64, 48);
        let mut img = blank(w, h);
        let spec = AnnotateSpec {
            scale_bar: Some(ScaleBarSpec::Length(1e12)),
            ..Default::default()
        };
        let ctx = Context {
            camera: &camera,
            ras: true,
            background: [1.0; 3],
            colorbar: None,
        };
        let t = std::time::Instant::now();
        let p = draw(&mut img, w, h, &spec, &ctx).unwrap();
        assert!(
            t.elapsed().as_secs_f64() < 5.0,
            "drawn pixel by pixel off the image"
        );
        assert!(p.scale_bar.unwrap().1 > 1e9);
        // The bar reaches the right edge.
        let y = (h as f32 - p.text_px * 0.6 - 1.0) as usize;
        assert!(img[y * w + w - 1][0] < 0.5);
        // One shorter than a pixel has nothing to draw: an error, not a label without a bar.
        let tiny = AnnotateSpec {
            scale_bar: Some(ScaleBarSpec::Length(1e-3)),
            ..Default::default()
        };
        let e = draw(&mut blank(w, h), w, h, &tiny, &ctx).unwrap_err();
        assert!(
            e.contains("annotate.scale_bar") && e.contains("below one pixel"),
            "{e}"
        );
    }

    #[test]
    fn nice_lengths_and_numbers() {
        assert_eq!(nice_length(37.0), 20.0);
        assert_eq!(nice_length(9.99), 5.0);
        assert_eq!(nice_length(10.0), 10.0);
        assert_eq!(nice_length(0.0031), 0.002);
        assert_eq!(format_number(10.0), "10");
        assert_eq!(format_number(0.25), "0.25");
        assert_eq!(format_number(1234.5678), "1235");
        assert_eq!(format_number(-0.00012346), "-0.0001235");
        assert_eq!(format_number(9999.4), "9999");
        assert_eq!(format_number(-22776158208.0), "-2.278e10");
        assert_eq!(format_number(102083428352.0), "1.021e11");
        assert_eq!(format_number(20000.0), "2e4");
        assert_eq!(format_number(3.2e-7), "3.2e-7");
        // Rounding up to 1e4 is written as 1e4 is; negative zero is 0.
        assert_eq!(format_number(9999.6), "1e4");
        assert_eq!(format_number(-9999.6), "-1e4");
        assert_eq!(format_number(-0.0), "0");
        // A colour bar's ends: more digits until they differ (a narrow window on offset
        // data), at most 9; equal ends stay as they are.
        let s = |a: &str, b: &str| (a.to_string(), b.to_string());
        assert_eq!(format_ends([0.0, 2.5]), s("0", "2.5"));
        assert_eq!(format_ends([9999.5, 10000.5]), s("9999.5", "1.00005e4"));
        assert_eq!(format_ends([0.99999, 1.00001]), s("0.99999", "1.00001"));
        assert_eq!(format_ends([273.15, 273.16]), s("273.15", "273.16"));
        assert_eq!(format_ends([7.0, 7.0]), s("7", "7"));
        // Characters the bundled font lacks, each once; spaces always draw.
        assert_eq!(missing_glyphs("Fibres α-β → 中文 中"), vec!['中', '文']);
        assert!(missing_glyphs("T1 (mm) ±0.5").is_empty());
    }

    fn blank(w: usize, h: usize) -> Vec<[f32; 4]> {
        vec![[1.0, 1.0, 1.0, 1.0]; w * h]
    }

    /// Pixels that differ from white inside `r` (grown by 2) and outside every box.
    fn ink(img: &[[f32; 4]], w: usize, boxes: &[Rect]) -> (usize, usize) {
        let (mut inside, mut outside) = (0, 0);
        for (i, p) in img.iter().enumerate() {
            if p[0] < 0.99 || p[1] < 0.99 || p[2] < 0.99 {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                if boxes.iter().any(|b| {
                    x >= b[0] - 3.0 && x <= b[2] + 3.0 && y >= b[1] - 3.0 && y <= b[3] + 3.0
                }) {
                    inside += 1;
                } else {
                    outside += 1;
                }
            }
        }
        (inside, outside)
    }

    /// An orthographic view from +z, 100 world units high.
    fn top_view() -> Camera {
        Camera::look_at(
            DVec3::new(0.0, 0.0, 400.0),
            DVec3::ZERO,
            DVec3::Y,
            Projection::Orthographic { height: 100.0 },
            [DVec3::splat(-50.0), DVec3::splat(50.0)],
        )
        .unwrap()
    }

    /// The context of RAS data on a white background.
    fn on_white<'a>(camera: &'a Camera, colorbar: Option<&'a ColorBar>) -> Context<'a> {
        Context {
            camera,
            ras: true,
            background: [1.0; 3],
            colorbar,
        }
    }

    /// A title wider than the image is cut with an ellipsis inside the margins (it lost its
    /// ends on both sides before): no ink in the outer columns, and ink at the top.
    #[test]
    fn a_long_title_stays_inside_the_image() {
        let camera = top_view();
        let (w, h) = (200usize, 150usize);
        let spec = AnnotateSpec {
            title: Some("W".repeat(200)),
            ..Default::default()
        };
        let mut img = blank(w, h);
        let p = draw(&mut img, w, h, &spec, &on_white(&camera, None)).unwrap();
        let dark = |xs: std::ops::Range<usize>| {
            (0..h)
                .flat_map(|y| xs.clone().map(move |x| y * w + x))
                .filter(|&i| img[i][0] < 0.5)
                .count()
        };
        assert_eq!(dark(0..3) + dark(w - 3..w), 0);
        assert!(dark(10..w - 10) > 100);
        let t = p.title.unwrap();
        assert!(t[0] >= 3.0 && t[2] <= w as f32 - 3.0, "{t:?}");
    }

    /// A colour bar's label longer than the bar, or than the image, stays inside the image
    /// (moved left, then cut with an ellipsis): no ink in the right margin.
    #[test]
    fn a_long_colour_bar_label_stays_inside_the_image() {
        let camera = top_view();
        let bar = ColorBar {
            label: "v".into(),
            map: "transfer function".into(),
            range: [0.0, 63.0],
            colors: vec![[0.5; 3]; 64],
        };
        let (w, h) = (256usize, 192usize);
        for label in ["a field with a long name", &"very long ".repeat(20)] {
            let spec = AnnotateSpec {
                colorbar: Some("volume".into()),
                colorbar_label: Some(label.to_string()),
                ..Default::default()
            };
            let mut img = blank(w, h);
            draw(&mut img, w, h, &spec, &on_white(&camera, Some(&bar))).unwrap();
            // Text 9 px high, margins 5.4 px (the bar's frame reaches 2.6 px from the edge):
            // nothing dark in the last 3 columns.
            let dark = (0..h)
                .flat_map(|y| (w - 3..w).map(move |x| y * w + x))
                .filter(|&i| img[i][0] < 0.5)
                .count();
            assert_eq!(dark, 0, "{label}");
            // The label was drawn (ink above the bar).
            let above = (h - 40..h - 24)
                .flat_map(|y| (0..w).map(move |x| y * w + x))
                .filter(|&i| img[i][0] < 0.5)
                .count();
            assert!(above > 20, "{label}: {above}");
        }
    }

    #[test]
    fn a_widened_colour_bar_goes_above_the_bottom_orientation_label() {
        let camera = top_view();
        let bar = viridis_bar("fractional anisotropy", [0.0001234, 12345.6]);
        let spec = AnnotateSpec {
            colorbar: Some("slices.0".into()),
            orientation: true,
            ..Default::default()
        };
        let overlap = |a: Rect, b: Rect| a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3];
        for (w, h) in [(160usize, 120usize), (200, 150)] {
            let mut img = blank(w, h);
            let p = draw(&mut img, w, h, &spec, &on_white(&camera, Some(&bar))).unwrap();
            let label = p.labels[3].1;
            let cb = p.colorbar.unwrap();
            let framed = [cb[0] - 2.0, cb[1] - 2.0, cb[2] + 2.0, cb[3] + 2.0];
            for r in [framed, p.colorbar_ends[0], p.colorbar_ends[1]] {
                assert!(!overlap(r, label), "{r:?} over {label:?} at {w}x{h}");
            }
        }
    }

    #[test]
    fn a_widened_colour_bar_goes_above_the_scale_bar() {
        let camera = top_view();
        // Ends of 9 digits: "12345.6781", "12345.6789".
        let bar = viridis_bar("p", [12345.6781, 12345.6789]);
        let spec = AnnotateSpec {
            colorbar: Some("slices.0".into()),
            scale_bar: Some(ScaleBarSpec::Word("auto".into())),
            ..Default::default()
        };
        let overlap = |a: Rect, b: Rect| a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3];
        for (w, h) in [(160usize, 120usize), (200, 150), (640, 480)] {
            let mut img = blank(w, h);
            let p = draw(&mut img, w, h, &spec, &on_white(&camera, Some(&bar))).unwrap();
            let (sb, sl) = (p.scale_bar.unwrap().0, p.scale_label.unwrap());
            let cb = p.colorbar.unwrap();
            // The bar's frame and halo reach 2 pixels beyond it.
            let framed = [cb[0] - 2.0, cb[1] - 2.0, cb[2] + 2.0, cb[3] + 2.0];
            for r in [framed, p.colorbar_ends[0], p.colorbar_ends[1]] {
                for s in [sb, sl] {
                    assert!(!overlap(r, s), "{r:?} over {s:?} at {w}x{h}");
                }
                assert!(r[1] >= 0.0, "{r:?} above the image at {w}x{h}");
            }
            // Where there is room, the bars share the bottom row.
            if w == 640 {
                assert!(cb[3] > sl[1], "{cb:?} {sl:?}");
            }
        }
    }

    #[test]
    fn a_colour_bars_end_labels_stay_apart_on_a_thumbnail() {
        let camera = top_view();
        let bar = viridis_bar("mfrac", [1.401e-44, 0.005667]);
        let spec = AnnotateSpec {
            colorbar: Some("slices.0".into()),
            ..Default::default()
        };
        for (w, h) in [(160usize, 120usize), (240, 180), (400, 300)] {
            let mut img = blank(w, h);
            let p = draw(&mut img, w, h, &spec, &on_white(&camera, Some(&bar))).unwrap();
            let (a, b) = (p.colorbar_ends[0], p.colorbar_ends[1]);
            let px = a[3] - a[1];
            // Apart by at least half a text height, inside the image, under the bar.
            assert!(b[0] - a[2] >= 0.5 * px, "{a:?} {b:?} at {w}x{h}");
            assert!(a[0] >= 0.0 && b[2] <= w as f32, "{a:?} {b:?} at {w}x{h}");
            let cb = p.colorbar.unwrap();
            assert!(cb[2] - cb[0] >= (0.3 * w as f32).round(), "{cb:?}");
        }
    }

    #[test]
    fn the_layout_scales_with_the_image_and_the_scale_bar_measures_the_world() {
        let camera = top_view();
        let bar = viridis_bar("speed", [0.0, 2.5]);
        let spec = AnnotateSpec {
            title: Some("Flow".into()),
            orientation: true,
            scale_bar: Some(ScaleBarSpec::Length(20.0)),
            colorbar: Some("lines.0".into()),
            ..Default::default()
        };
        let mut prev: Option<(usize, Placed)> = None;
        for (w, h) in [(400usize, 300usize), (800, 600), (1600, 1200), (410, 307)] {
            let mut img = blank(w, h);
            let ctx = Context {
                camera: &camera,
                ras: true,
                background: [1.0; 3],
                colorbar: Some(&bar),
            };
            let p = draw(&mut img, w, h, &spec, &ctx).unwrap();
            // Orthographic, 100 world units over h pixels: 20 units are h / 5 pixels, the
            // nearest whole number of them (61 of 61.4 at 307 pixels), drawn exactly.
            let (rect, len, world) = p.scale_bar.unwrap();
            assert_eq!(world, 20.0);
            assert_eq!(len, (h as f64 / 5.0).round(), "{len}");
            let around = (rect[0] as usize).saturating_sub(2)..(rect[2] as usize + 2).min(w);
            let drawn: Vec<usize> = around
                .filter(|&x| img[(rect[1] as usize + 1) * w + x][0] < 0.01)
                .collect();
            assert_eq!(drawn.len() as f64, len, "{} drawn of {len}", drawn.len());
            // Everything lies inside the image, nothing overlaps, and ink is only where
            // something was placed.
            let mut boxes: Vec<Rect> = p.labels.iter().map(|l| l.1).collect();
            boxes.extend(p.title);
            boxes.push(rect);
            boxes.push(p.colorbar.unwrap());
            for b in &boxes {
                assert!(
                    b[0] >= 0.0 && b[1] >= 0.0 && b[2] <= w as f32 && b[3] <= h as f32,
                    "{b:?} in {w}x{h}"
                );
            }
            for (i, a) in boxes.iter().enumerate() {
                for b in &boxes[i + 1..] {
                    let apart = a[2] <= b[0] || b[2] <= a[0] || a[3] <= b[1] || b[3] <= a[1];
                    assert!(apart, "{a:?} overlaps {b:?} at {w}x{h}");
                }
            }
            // The end labels' halos (from 3 rows above their boxes) clear the bar's frame
            // (its rows end at the bar's bottom + 1, cut to a whole row): they do not eat into
            // it (they did with the labels 0.2 text heights under the bar at 400 x 300).
            let cb = p.colorbar.unwrap();
            assert_eq!(p.colorbar_ends.len(), 2);
            for e in &p.colorbar_ends {
                assert!(
                    e[1].round() - 3.0 >= (cb[3] + 1.0).trunc(),
                    "{e:?} under {cb:?} at {w}x{h}"
                );
            }
            // The colour bar's ends are the colouring's ends.
            let yc = ((cb[1] + cb[3]) * 0.5) as usize;
            let left = img[yc * w + cb[0] as usize];
            let right = img[yc * w + cb[2] as usize - 1];
            for k in 0..3 {
                assert!((left[k] - bar.colors[0][k]).abs() < 1e-6);
                assert!((right[k] - bar.colors[63][k]).abs() < 1e-6);
            }
            // Labels above and below the bar and the ticks are in the grown boxes except the
            // text around the bars: the only ink outside is that text, bounded.
            let (inside, outside) = ink(&img, w, &boxes);
            assert!(inside > 0);
            assert!(
                (outside as f64) < 0.02 * (w * h) as f64,
                "{outside} stray pixels"
            );
            // Doubling the image doubles the layout (the last size is not a double).
            if let Some((pw, pp)) = prev.as_ref().filter(|(pw, _)| w == 2 * pw) {
                let s = (w / *pw) as f32;
                assert!((p.text_px / pp.text_px - s).abs() < 0.01);
                let (a, b) = (p.title.unwrap(), pp.title.unwrap());
                assert!(
                    ((a[2] - a[0]) / (b[2] - b[0]) - s).abs() < 0.15,
                    "title width"
                );
                assert!((a[1] / b[1] - s).abs() < 0.01, "title margin");
            }
            prev = Some((w, p));
        }
    }
}
