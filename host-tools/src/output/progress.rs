//! Progress for the long commands (`tradeoff`, `stability`, long `measure`
//! runs), drawn on stderr only when stderr is a terminal: indicatif's stderr
//! draw target hides itself otherwise, so logs, pipes, tests and CI get no
//! control characters, and stdout (the tables) is never touched.
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::time::Duration;

/// A bar over `len` steps (cases, points), labelled `what`.
pub fn bar(len: u64, what: &str) -> ProgressBar {
    bar_to(len, what, ProgressDrawTarget::stderr())
}

/// A spinner with a message, for work whose length is not known in steps.
pub fn spinner(what: &str) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
    pb.set_style(ProgressStyle::with_template("{spinner} [{elapsed}] {msg}").expect("a fixed template"));
    pb.set_message(what.to_string());
    if !pb.is_hidden() {
        pb.enable_steady_tick(Duration::from_millis(200));
    }
    pb
}

fn bar_to(len: u64, what: &str, target: ProgressDrawTarget) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(Some(len), target);
    pb.set_style(
        ProgressStyle::with_template("{msg} [{elapsed}] {wide_bar} {pos}/{len} (eta {eta})").expect("a fixed template"),
    );
    pb.set_message(what.to_string());
    pb
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hidden_target_draws_nothing_and_still_counts() {
        let pb = bar_to(10, "cases", ProgressDrawTarget::hidden());
        assert!(pb.is_hidden());
        pb.inc(3);
        assert_eq!(pb.position(), 3);
        pb.finish_and_clear();
    }
}
