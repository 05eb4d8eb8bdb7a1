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

    /// Frame `index` (from 0) of `n`, written to `path` in `ms` milliseconds.
    pub fn frame(&self, index: usize, n: usize, path: &std::path::Path, ms: f64) {
        match &self.bar {
            Some(bar) => {
                if bar.is_hidden() {
                    bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
                    bar.set_length(n as u64);
                }
                bar.set_message(path.display().to_string());
                bar.inc(1);
            }
            None => eprintln!("frame {}/{n} {} {ms:.1} ms", index + 1, path.display()),
        }
    }
}

impl Drop for Frames {
    fn drop(&mut self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}
