//! Standard output for every command: written through [`out`], so that a closed pipe
//! (`umbra scene s.toml | head -1`) ends the program quietly with status 0 instead of a panic.

use std::io::Write as _;

/// Writes `text` and a newline to standard output. A closed pipe exits the process with status
/// 0 (whoever read the output has what they wanted); another failure is an error.
pub fn out(text: impl std::fmt::Display) -> Result<(), String> {
    write(format_args!("{text}\n"))
}

/// Writes `text` to standard output as it is (no newline added); see [`out`].
pub fn out_raw(text: impl std::fmt::Display) -> Result<(), String> {
    write(format_args!("{text}"))
}

/// Writes a value as pretty-printed JSON and a newline; see [`out`].
pub fn out_json_pretty(value: &impl serde::Serialize) -> Result<(), String> {
    out(serde_json::to_string_pretty(value).map_err(|e| e.to_string())?)
}

/// Writes a value as one line of JSON; see [`out`].
pub fn out_json(value: &impl serde::Serialize) -> Result<(), String> {
    out(serde_json::to_string(value).map_err(|e| e.to_string())?)
}

fn write(args: std::fmt::Arguments) -> Result<(), String> {
    let mut stdout = std::io::stdout().lock();
    match stdout.write_fmt(args).and_then(|()| stdout.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(0),
        Err(e) => Err(format!("standard output: {e}")),
    }
}
