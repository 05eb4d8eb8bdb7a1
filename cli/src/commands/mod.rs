//! One module per subcommand: its arguments (`Args`, the doc comments are the help) and its
//! `run`, which turns them into the libraries' types, calls the library and prints. The value
//! types several commands share are here.

pub mod convert;
pub mod demo;
pub mod info;
pub mod iso;
pub mod render;
pub mod resample;
pub mod scene;
pub mod sweep;
pub mod synth;
pub mod trace;
pub mod tracts;
pub mod tubes;
pub mod view;

use volume::FieldSelector;

/// `--field NAME`, `NAME:magnitude` or `NAME:x|y|z`.
/// The note for a tractogram written as `.tck` (optionally gzipped) whose attributes that
/// format cannot hold: it names them; `None` for other formats or without attributes.
pub fn tck_drops_note(output: &std::path::Path, s: &::tubes::Streamlines) -> Option<String> {
    let name = output.to_string_lossy().to_ascii_lowercase();
    let names: Vec<&str> = s
        .point_attributes
        .iter()
        .chain(&s.line_attributes)
        .map(|a| a.name.as_str())
        .collect();
    (name.trim_end_matches(".gz").ends_with(".tck") && !names.is_empty()).then(|| {
        format!(
            "{}: .tck holds positions only: the attributes {} are not written (use .trk or .trx \
             to keep them)",
            output.display(),
            names.join(", ")
        )
    })
}

pub fn field_selector(s: &str) -> Result<FieldSelector, String> {
    s.parse().map_err(|e: volume::VolumeError| e.to_string())
}

/// One item of a comma-separated list (`value_delimiter = ','`), spaces around it ignored.
pub fn list_item<T: std::str::FromStr>(s: &str) -> Result<T, String> {
    s.trim()
        .parse::<T>()
        .map_err(|_| format!("'{}' is not valid here", s.trim()))
}

/// A positive finite number (a radius, a tolerance).
pub fn positive(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err("must be a positive number".into()),
    }
}

/// A finite number (an angle, an offset).
pub fn finite64(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err("must be a finite number".into()),
    }
}

/// A finite number of at least 0 (a speed).
pub fn nonnegative(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err("must be a number of at least 0".into()),
    }
}

/// A positive finite `f32` (a tolerance in voxels).
pub fn positive32(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err("must be a positive number".into()),
    }
}

/// A number from 0 to 1 (an opacity).
pub fn unit(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err("must be a number from 0 to 1".into()),
    }
}

/// An angle in degrees in (0, 180] (a largest turn).
pub fn degrees(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v <= 180.0 => Ok(v),
        _ => Err("must be an angle in degrees, more than 0 and at most 180".into()),
    }
}

/// A finite number (an iso level).
pub fn finite(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err("must be a finite number".into()),
    }
}

/// `--inside above|below`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Inside {
    Above,
    Below,
}

impl From<Inside> for volume::distance_sweep::Inside {
    fn from(a: Inside) -> Self {
        match a {
            Inside::Above => volume::distance_sweep::Inside::Above,
            Inside::Below => volume::distance_sweep::Inside::Below,
        }
    }
}

/// `--method`: a render method, one per row of the method table (`engine::method::METHODS`),
/// by the name scene files give it, so that a new row needs nothing here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Method(pub ::scene::spec::Method);

impl clap::ValueEnum for Method {
    fn value_variants<'a>() -> &'a [Self] {
        static ALL: std::sync::LazyLock<Vec<Method>> = std::sync::LazyLock::new(|| {
            engine::method::METHODS
                .iter()
                .map(|d| Method(d.method))
                .collect()
        });
        &ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        let d = self.0.desc();
        Some(clap::builder::PossibleValue::new(d.name).help(d.summary))
    }
}

impl From<Method> for ::scene::spec::Method {
    fn from(m: Method) -> Self {
        m.0
    }
}

impl Method {
    /// The name scene files give the method (`render.method`).
    pub fn name(self) -> &'static str {
        self.0.desc().name
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum as _;

    #[test]
    fn method_flags_name_the_methods_scene_files_name() {
        assert_eq!(
            Method::value_variants().len(),
            engine::method::METHODS.len()
        );
        for m in Method::value_variants() {
            let flag = m.to_possible_value().unwrap().get_name().to_string();
            let spec: ::scene::spec::Method = (*m).into();
            assert_eq!(serde_json::to_value(spec).unwrap(), flag.as_str());
            assert_eq!(m.name(), flag);
            assert_eq!(Method::from_str(&flag, false).unwrap(), *m);
        }
        assert!(Method::from_str("fancy", false).is_err());
    }

    #[test]
    fn positive_and_finite_numbers() {
        assert_eq!(positive("0.5").unwrap(), 0.5);
        for bad in ["0", "-1", "inf", "nan", "x"] {
            assert!(positive(bad).is_err(), "{bad}");
        }
        assert_eq!(finite("-2").unwrap(), -2.0);
        for bad in ["nan", "inf", "1e40", "x"] {
            assert!(finite(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn list_items_are_trimmed_and_bad_ones_named() {
        assert_eq!(list_item::<f64>(" 0.5 ").unwrap(), 0.5);
        let e = list_item::<usize>("x").unwrap_err();
        assert!(e.contains("'x'"), "{e}");
    }
}
