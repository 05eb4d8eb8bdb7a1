//! The benchmarks' charts (plotters): log-log scatter plots as SVG and PNG, drawn with the
//! bundled DejaVu Sans (no system fonts needed).

use std::path::Path;

const FONT: &[u8] = scene::annotate::FONT;

/// A log-log scatter chart: named point series and an optional line (e.g. a Pareto front).
pub struct Plot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<(String, Vec<(f64, f64)>)>,
    pub line: Option<(String, Vec<(f64, f64)>)>,
}

/// A log axis's range for data in `[lo, hi]`: out to whole powers of ten on both sides, so that
/// the axis holds at least one labelled decade (a log axis within one decade prints no labels).
fn decade_range(lo: f64, hi: f64) -> (f64, f64) {
    let lo = lo.max(1e-9);
    let hi = hi.max(lo);
    let a = 10f64.powf(lo.log10().floor());
    let mut b = 10f64.powf(hi.log10().ceil());
    if b <= a {
        b = a * 10.0;
    }
    (a, b)
}

/// The labelled points of a log axis over `[lo, hi]` (whole decades, [`decade_range`]): 1, 2
/// and 5 of each decade.
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let mut out = vec![];
    let mut d = lo;
    while d <= hi * (1.0 + 1e-9) {
        for m in [1.0, 2.0, 5.0] {
            let v = d * m;
            if v <= hi * (1.0 + 1e-9) {
                out.push(v);
            }
        }
        d *= 10.0;
    }
    out
}

/// An axis label: three significant digits, no trailing zeros (`0.25`, `90`, `1e-4`).
fn tick(v: f64) -> String {
    if !(v.is_finite() && v > 0.0) {
        return format!("{v}");
    }
    let e = v.log10().floor() as i32;
    if !(-3..=5).contains(&e) {
        return format!("{v:.0e}");
    }
    let decimals = (2 - e).max(0) as usize;
    let s = format!("{v:.decimals$}");
    match s.contains('.') {
        true => s.trim_end_matches('0').trim_end_matches('.').to_string(),
        false => s,
    }
}

fn draw<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    p: &Plot,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    use plotters::prelude::*;
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    let all = p.series.iter().flat_map(|s| s.1.iter());
    let (x0, x1, y0, y1) = all.fold(
        (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64),
        |(a, b, c, d), q| (a.min(q.0), b.max(q.0), c.min(q.1), d.max(q.1)),
    );
    if !(x0.is_finite() && y0.is_finite()) {
        return Err("nothing to chart".into());
    }
    let (x0, x1) = decade_range(x0, x1);
    let (y0, y1) = decade_range(y0, y1);
    let mut c = ChartBuilder::on(&root)
        .caption(&p.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(
            (x0..x1).log_scale().with_key_points(log_ticks(x0, x1)),
            (y0..y1).log_scale().with_key_points(log_ticks(y0, y1)),
        )
        .map_err(err)?;
    // Labels at 1, 2 and 5 of each decade where they fit, at three significant digits (a range
    // within one decade read "1.0" alone, and "90.0" ran into "100.0").
    c.configure_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .x_labels(32)
        .y_labels(32)
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .draw()
        .map_err(err)?;
    for (i, (name, pts)) in p.series.iter().enumerate() {
        let col = Palette99::pick(i).to_rgba();
        c.draw_series(pts.iter().map(|q| Circle::new(*q, 4, col.filled())))
            .map_err(err)?
            .label(name.clone())
            .legend(move |(x, y)| Circle::new((x, y), 4, col.filled()));
    }
    if let Some((name, pts)) = &p.line {
        c.draw_series(LineSeries::new(pts.clone(), BLACK.stroke_width(1)))
            .map_err(err)?
            .label(name.clone())
            .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], BLACK));
    }
    // In the upper right, where a speed-accuracy chart's worst points are (its best are low
    // and to the left).
    c.configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

/// Writes `p` as `<dir>/<stem>.svg` and `<dir>/<stem>.png` (800 x 560).
pub fn write_chart(dir: &Path, stem: &str, p: &Plot) -> Result<(), String> {
    plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, FONT)
        .map_err(|_| "the chart font does not load".to_string())?;
    let mut text = String::new();
    {
        let root = plotters::prelude::SVGBackend::with_string(&mut text, (800, 560));
        draw(
            plotters::prelude::IntoDrawingArea::into_drawing_area(root),
            p,
        )?;
    }
    volume::write_atomic(&dir.join(format!("{stem}.svg")), text.as_bytes())
        .map_err(|e| e.to_string())?;
    let mut px = vec![0u8; 800 * 560 * 3];
    {
        let root = plotters::prelude::BitMapBackend::with_buffer(&mut px, (800, 560));
        draw(
            plotters::prelude::IntoDrawingArea::into_drawing_area(root),
            p,
        )?;
    }
    let png: image::RgbImage = image::RgbImage::from_raw(800, 560, px).ok_or("chart buffer")?;
    let mut bytes = Vec::new();
    png.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| e.to_string())?;
    volume::write_atomic(&dir.join(format!("{stem}.png")), &bytes).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    #[test]
    fn log_axes_hold_at_least_one_labelled_decade() {
        assert_eq!(super::decade_range(0.21, 0.24), (0.1, 1.0));
        assert_eq!(super::decade_range(3.0, 450.0), (1.0, 1000.0));
        assert_eq!(super::decade_range(1.0, 1.0), (1.0, 10.0));
        let (a, b) = super::decade_range(0.0, 0.0);
        assert!(a > 0.0 && b >= 10.0 * a);
    }

    use super::{log_ticks, tick};

    #[test]
    fn log_axes_are_labelled_at_1_2_and_5_of_each_decade() {
        let t = log_ticks(0.1, 10.0);
        let want = [0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0];
        assert_eq!(t.len(), want.len(), "{t:?}");
        assert!(
            t.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-9 * b),
            "{t:?}"
        );
    }

    #[test]
    fn ticks_have_three_significant_digits_and_no_trailing_zeros() {
        for (v, want) in [
            (0.25, "0.25"),
            (90.0, "90"),
            (100.0, "100"),
            (1.0, "1"),
            (0.002, "0.002"),
            (1234.0, "1234"),
            (1e-4, "1e-4"),
            (2e6, "2e6"),
        ] {
            assert_eq!(tick(v), want, "{v}");
        }
    }
}
