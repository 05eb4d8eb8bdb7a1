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
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(err)?;
    c.configure_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
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
    c.configure_series_labels()
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
}
