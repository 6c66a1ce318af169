//! Progress on long work, on a terminal and off it.
//!
//! On a terminal, indicatif's bar. Off one (a log, `nohup`, a CI job) indicatif draws
//! nothing, so a recovery of five minutes said nothing until it ended and a render of
//! absurd samples never said how long it would take. There the bar's text is written as a
//! plain line now and then instead (`LogLines`): once work has gone on for
//! [`FIRST_LINE_AFTER`], then at most every [`LINE_EVERY`], so that short runs (and the
//! tests) print none.

use std::io::{IsTerminal, Write};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{
    HumanDuration, ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle, TermLike,
};

/// How long work goes on before its first line off a terminal.
pub const FIRST_LINE_AFTER: Duration = Duration::from_secs(10);

/// The least time between two lines off a terminal.
pub const LINE_EVERY: Duration = Duration::from_secs(30);

/// A bar of `len` steps headed by `what`, counting `unit` ("rows"; empty for none).
pub fn bar(len: u64, what: &str, unit: &str) -> ProgressBar {
    let unit = if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    };
    let bar = if std::io::stderr().is_terminal() {
        let template = format!("{{msg:>14}} [{{bar:40}}] {{pos}}/{{len}}{unit}, {{eta}} left");
        ProgressBar::new(len).with_style(style(&template))
    } else {
        let target = ProgressDrawTarget::term_like_with_hz(Box::new(LogLines::new()), 1);
        let template = format!("relume: {{msg}}: {{pos}}/{{len}}{unit} after {{elapsed}}{{left}}");
        let style = style(&template).with_key("left", time_left);
        ProgressBar::with_draw_target(Some(len), target).with_style(style)
    };
    bar.set_message(what.to_string());
    bar
}

/// ", about 1m left" once a step is done; nothing before, where indicatif's estimate reads
/// 0 s ("diffuse again: 0/30 after 0s, about 0s left").
fn time_left(state: &ProgressState, w: &mut dyn std::fmt::Write) {
    if state.pos() > 0 {
        let _ = write!(w, ", about {} left", HumanDuration(state.eta()));
    }
}

fn style(template: &str) -> ProgressStyle {
    ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar())
}

/// A "terminal" that writes the bar's text to stderr as a line of its own, now and then
/// ([`Clock::due`]). indicatif redraws by moving the cursor and clearing lines, which a
/// log has no use for, so those are ignored and the text of each draw is gathered until
/// its `flush`.
#[derive(Debug)]
struct LogLines {
    text: Mutex<String>,
}

/// When lines were written, for the whole run: a recovery's stages each have a bar, most
/// shorter than [`FIRST_LINE_AFTER`], and it is the run that a log's reader waits on.
#[derive(Clone, Copy, Debug)]
struct Clock {
    /// When the first bar was made.
    started: Instant,
    last_line: Option<Instant>,
}

static CLOCK: Mutex<Option<Clock>> = Mutex::new(None);

impl Clock {
    /// Whether a line is due at `now`.
    fn due(&self, now: Instant) -> bool {
        match self.last_line {
            None => now.duration_since(self.started) >= FIRST_LINE_AFTER,
            Some(last) => now.duration_since(last) >= LINE_EVERY,
        }
    }
}

/// `f` on the run's clock, started by the first call.
fn with_clock<T>(f: impl FnOnce(&mut Clock) -> T) -> T {
    // A panic elsewhere while drawing leaves the clock as it was; keep going.
    let mut clock = CLOCK.lock().unwrap_or_else(|e| e.into_inner());
    let clock = clock.get_or_insert_with(|| Clock {
        started: Instant::now(),
        last_line: None,
    });
    f(clock)
}

impl LogLines {
    fn new() -> LogLines {
        with_clock(|_| ());
        LogLines {
            text: Mutex::new(String::new()),
        }
    }

    /// The text of the draw that ends, if a line is due (the clock then says so).
    fn take_line(&self, clock: &mut Clock, now: Instant) -> Option<String> {
        let text = std::mem::take(&mut *self.text.lock().unwrap_or_else(|e| e.into_inner()));
        let text = text.trim();
        if text.is_empty() || !clock.due(now) {
            return None;
        }
        clock.last_line = Some(now);
        Some(text.to_string())
    }
}

impl TermLike for LogLines {
    fn width(&self) -> u16 {
        // Wide enough that indicatif never cuts the line.
        500
    }

    fn move_cursor_up(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }

    fn move_cursor_down(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }

    fn move_cursor_right(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }

    fn move_cursor_left(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }

    fn write_line(&self, s: &str) -> std::io::Result<()> {
        self.write_str(s)
    }

    fn write_str(&self, s: &str) -> std::io::Result<()> {
        self.text
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push_str(s);
        Ok(())
    }

    fn clear_line(&self) -> std::io::Result<()> {
        Ok(())
    }

    fn flush(&self) -> std::io::Result<()> {
        match with_clock(|clock| self.take_line(clock, Instant::now())) {
            Some(line) => writeln!(std::io::stderr(), "{line}"),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first line waits [`FIRST_LINE_AFTER`] from the first bar, the next
    /// [`LINE_EVERY`] after it.
    #[test]
    fn lines_are_due_after_a_while_and_then_now_and_then() {
        let start = Instant::now();
        let mut clock = Clock {
            started: start,
            last_line: None,
        };
        assert!(!clock.due(start + FIRST_LINE_AFTER / 2));
        assert!(clock.due(start + FIRST_LINE_AFTER));
        clock.last_line = Some(start + FIRST_LINE_AFTER);
        assert!(!clock.due(start + FIRST_LINE_AFTER + LINE_EVERY / 2));
        assert!(clock.due(start + FIRST_LINE_AFTER + LINE_EVERY));
    }

    /// A draw's pieces (a carriage return, the text, the filler that clears the rest of a
    /// terminal's line) come out as one trimmed line, and only when one is due; a draw
    /// that is not due is dropped, not kept for the next.
    #[test]
    fn a_draw_is_gathered_into_one_line() {
        let start = Instant::now();
        let mut clock = Clock {
            started: start,
            last_line: None,
        };
        let log = LogLines {
            text: Mutex::new(String::new()),
        };
        for piece in ["\r", "relume: final render: 3/8 rows", "     "] {
            log.write_str(piece).unwrap();
        }
        assert_eq!(log.take_line(&mut clock, start), None);
        log.write_str("relume: final render: 4/8 rows ").unwrap();
        let later = start + FIRST_LINE_AFTER;
        assert_eq!(
            log.take_line(&mut clock, later).as_deref(),
            Some("relume: final render: 4/8 rows")
        );
        assert_eq!(clock.last_line, Some(later));
    }
}
