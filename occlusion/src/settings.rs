//! A setting out of range, the one error type of every method's settings: the CPU models'
//! here and the GPU passes' in `engine` (which re-exports it), so the scene can map a field to
//! the key it came from.

/// A setting out of range: which field of its settings type, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct SettingError {
    pub field: &'static str,
    pub problem: String,
}

impl std::fmt::Display for SettingError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.problem)
    }
}

impl std::error::Error for SettingError {}

/// `Err` naming `field` when `ok` is false.
pub fn require(
    ok: bool,
    field: &'static str,
    problem: impl FnOnce() -> String,
) -> Result<(), SettingError> {
    if ok {
        Ok(())
    } else {
        Err(SettingError {
            field,
            problem: problem(),
        })
    }
}
