//! Progress on standard error, the only place indicatif is used: a spinner or a bar when
//! standard error is a terminal, plain lines (or nothing) when it is a file or a pipe. The
//! libraries hear nothing of it: they take callbacks (`stage: &dyn Fn(&str)`, a frame callback)
//! that these feed.

use std::io::IsTerminal as _;
use std::time::Duration;

fn stderr_is_terminal() -> bool {
    std::io::stderr().is_terminal()
}

/// The current stage of a long command.
pub struct Stages {
    bar: Option<indicatif::ProgressBar>,
    lines: bool,
}

impl Stages {
    /// A spinner with the stage's name on a terminal; elsewhere a line per stage when `lines`,
    /// else nothing.
    pub fn new(lines: bool) -> Stages {
        let bar = stderr_is_terminal().then(|| {
            let b = indicatif::ProgressBar::new_spinner();
            b.enable_steady_tick(Duration::from_millis(120));
            b
        });
        Stages { bar, lines }
    }

    /// Nothing at all (e.g. with `--json`).
    pub fn hidden() -> Stages {
        Stages {
            bar: None,
            lines: false,
        }
    }

    /// Shows that stage `m` has started.
    pub fn stage(&self, m: &str) {
        match &self.bar {
            Some(b) => b.set_message(m.to_string()),
            None if self.lines => eprintln!("{m}"),
            None => {}
        }
    }
}

impl Drop for Stages {
    fn drop(&mut self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

/// Items of a long loop (streamlines written, points read): a bar on a terminal, else a line
/// at every tenth of the way.
pub struct Counter {
    bar: Option<indicatif::ProgressBar>,
    what: String,
    total: u64,
    shown: std::cell::Cell<u64>,
}

impl Counter {
    pub fn new(what: &str, total: u64) -> Counter {
        let bar = stderr_is_terminal().then(|| {
            let b = indicatif::ProgressBar::new(total);
            b.set_message(what.to_string());
            b
        });
        Counter {
            bar,
            what: what.to_string(),
            total,
            shown: 0.into(),
        }
    }

    /// `done` of the total are finished.
    pub fn set(&self, done: u64) {
        match &self.bar {
            Some(b) => b.set_position(done),
            None => {
                let tenth = (done * 10) / self.total.max(1);
                if tenth > self.shown.get() {
                    self.shown.set(tenth);
                    eprintln!("{}: {done} of {}", self.what, self.total);
                }
            }
        }
    }
}

impl Drop for Counter {
    fn drop(&mut self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

/// Frames of a sequence: a bar on a terminal, else a line per frame.
pub struct Frames {
    bar: Option<indicatif::ProgressBar>,
}

impl Frames {
    pub fn new() -> Frames {
        Frames {
            bar: stderr_is_terminal().then(indicatif::ProgressBar::hidden),
        }
    }

    /// A long stage has started: its name beside the bar (a spinner until the first frame)
    /// on a terminal; nothing in logs, which get a line per frame.
    pub fn stage(&self, m: &str) {
        if let Some(b) = self.bar(None) {
            if b.length().is_none() {
                b.set_style(indicatif::ProgressStyle::default_spinner());
                b.enable_steady_tick(std::time::Duration::from_millis(120));
            }
            b.set_message(m.to_string());
        }
    }

    /// The bar, shown from the first frame on (so that a run with nothing to do shows none).
    fn bar(&self, n: Option<usize>) -> Option<&indicatif::ProgressBar> {
        let bar = self.bar.as_ref()?;
        if bar.is_hidden() {
            bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        }
        if let Some(n) = n {
            if bar.length().is_none() {
                // From a stage's spinner to the frames' bar.
                bar.set_style(indicatif::ProgressStyle::default_bar());
            }
            bar.set_length(n as u64);
        }
        Some(bar)
    }

    /// Frame `index` (its number in the sequence or manifest) written to `path` in `ms`
    /// milliseconds, one of `n` this run renders.
    pub fn done(
        &self,
        index: usize,
        name: Option<&str>,
        n: usize,
        path: &std::path::Path,
        ms: f64,
    ) {
        let name = name.map(|n| format!(" {n}")).unwrap_or_default();
        match self.bar(Some(n)) {
            Some(bar) => {
                bar.set_message(path.display().to_string());
                bar.inc(1);
            }
            None => eprintln!("frame {index}{name}: {} in {ms:.1} ms", path.display()),
        }
    }

    /// Frame `index` left as it is: its output is complete.
    pub fn skipped(&self, index: usize, name: Option<&str>, path: &std::path::Path) {
        let name = name.map(|n| format!(" {n}")).unwrap_or_default();
        match self.bar(None) {
            Some(bar) => {
                // Printed with the bar cleared and drawn again below it (`println` on a bar
                // that has not drawn yet left the line unended, and the bar erased it).
                bar.suspend(|| {
                    eprintln!(
                        "frame {index}{name}: {} is complete, skipped",
                        path.display()
                    )
                });
                bar.inc(1);
            }
            None => eprintln!(
                "frame {index}{name}: {} is complete, skipped",
                path.display()
            ),
        }
    }

    /// Frame `index` failed (the others go on).
    pub fn failed(&self, index: usize, name: Option<&str>, path: &std::path::Path, error: &str) {
        let name = name.map(|n| format!(" {n}")).unwrap_or_default();
        let line = format!(
            "frame {index}{name}: {} FAILED: {}",
            path.display(),
            one_line(error)
        );
        match self.bar(None) {
            Some(bar) => {
                bar.suspend(|| eprintln!("{line}"));
                bar.inc(1);
            }
            None => eprintln!("{line}"),
        }
    }
}

/// An error on one line, as a log's per-frame line must be (`grep FAILED` finds its cause): a
/// TOML parser's quote of the line and its marks (`  |`, `1 | [volume`, `  |   ^`) left out,
/// the other lines joined by ": ".
pub fn one_line(error: &str) -> String {
    let quote = |l: &str| {
        let t = l.trim_start();
        let digits = t.trim_start_matches(|c: char| c.is_ascii_digit());
        digits.trim_start().starts_with('|')
    };
    error
        .lines()
        .filter(|l| !l.trim().is_empty() && !quote(l))
        .map(str::trim)
        .collect::<Vec<_>>()
        .join(": ")
}

impl Drop for Frames {
    fn drop(&mut self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

#[cfg(test)]
mod one_line_tests {
    use super::one_line;

    #[test]
    fn a_toml_error_becomes_one_line_with_its_place_and_cause() {
        let e = "m/lists/broken.toml: TOML parse error at line 1, column 8\n  |\n1 | [volume\n  |        ^\nunclosed table, expected `]`\n";
        assert_eq!(
            one_line(e),
            "m/lists/broken.toml: TOML parse error at line 1, column 8: unclosed table, expected `]`"
        );
        assert_eq!(one_line("plain"), "plain");
        // A line of the message that merely holds a bar is kept.
        assert_eq!(one_line("a\nvalue a | b"), "a: value a | b");
    }
}
