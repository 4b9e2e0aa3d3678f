//! Runs a target over N mutated inputs and reports what went wrong.

use crate::mutate::Mutator;
use crate::{CountingAlloc, Target};
use serde::Serialize;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::sync::{Mutex, Once};
use std::time::Instant;

/// Findings kept per kind (the counts are complete).
const SAMPLES_KEPT: usize = 5;

/// What a campaign on one target found.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TargetReport {
    /// The target's name.
    pub target: String,
    /// Inputs run.
    pub inputs: u64,
    /// Inputs accepted (`Ok`).
    pub accepted: u64,
    /// Inputs rejected with an error.
    pub rejected: u64,
    /// Inputs that panicked, inside the parser or out of it (counted by the panic hook, so a panic
    /// a parser wrapper caught and turned into an error still counts).
    pub panics: u64,
    /// Inputs whose only panics were in a third-party crate's source and were caught by a target
    /// that catches them on purpose ([`Target::catches_dependency_panics`]): not findings.
    pub caught_dependency_panics: u64,
    /// Rejections whose message is empty.
    pub empty_messages: u64,
    /// Rejections whose message lacks the target's required name (file or field).
    pub unnamed_errors: u64,
    /// Inputs whose peak live allocation exceeded the budget.
    pub over_budget: u64,
    /// The largest peak live allocation of one input above the live bytes before it (bytes);
    /// `None` without a counting allocator.
    pub max_peak_bytes: Option<u64>,
    /// The input that reached `max_peak_bytes`.
    pub max_peak_input: Option<u64>,
    /// The budget per input (bytes).
    pub budget_bytes: u64,
    /// Wall time of the campaign (s).
    pub seconds: f64,
    /// Up to five findings: input index and what happened.
    pub samples: Vec<String>,
}

impl TargetReport {
    /// True when nothing went wrong: no panic, every rejection named, every input within budget.
    pub fn clean(&self) -> bool {
        self.panics == 0
            && self.empty_messages == 0
            && self.unnamed_errors == 0
            && self.over_budget == 0
    }
}

static PANICS: AtomicU64 = AtomicU64::new(0);
/// Panics whose location is a crates.io dependency's source (`…/registry/src/…`).
static DEPENDENCY_PANICS: AtomicU64 = AtomicU64::new(0);
static LAST_PANIC: Mutex<Option<String>> = Mutex::new(None);

static IN_INPUT: AtomicBool = AtomicBool::new(false);

/// Wraps the panic hook: a panic while an input runs is counted and its message kept quietly (the
/// runner reports it); any other panic goes to the previous hook. Idempotent.
pub fn install_quiet_panic_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !IN_INPUT.load(Relaxed) {
                return previous(info);
            }
            PANICS.fetch_add(1, Relaxed);
            if info
                .location()
                .is_some_and(|l| l.file().contains("/registry/src/"))
            {
                DEPENDENCY_PANICS.fetch_add(1, Relaxed);
            }
            let mut last = LAST_PANIC.lock().unwrap_or_else(|p| p.into_inner());
            *last = Some(info.to_string());
        }));
    });
}

fn note(report: &mut TargetReport, text: String) {
    if report.samples.len() < SAMPLES_KEPT {
        report.samples.push(text);
    }
}

/// Runs `inputs` inputs of `target` (input `i` is `Mutator::input(seed, i)`), one at a time.
/// `target_index` is the target's place in [`crate::all_targets`] (named by `alloc`'s refusal line).
/// With `alloc`, each input's peak live bytes are measured against `budget_bytes`.
pub fn run_target(
    target: &Target,
    target_index: usize,
    inputs: u64,
    seed: u64,
    alloc: Option<&CountingAlloc>,
    budget_bytes: u64,
) -> TargetReport {
    install_quiet_panic_hook();
    let mutator = Mutator::new((target.seeds)(), target.max_len);
    let mut report = TargetReport {
        target: target.name.to_string(),
        budget_bytes,
        ..TargetReport::default()
    };
    let start = Instant::now();
    for i in 0..inputs {
        let input = mutator.input(seed, i);
        let panics_before = PANICS.load(Relaxed);
        let dependency_panics_before = DEPENDENCY_PANICS.load(Relaxed);
        let baseline = alloc.map(|a| {
            a.set_current(target_index, i);
            a.reset_peak()
        });
        IN_INPUT.store(true, Relaxed);
        let result = catch_unwind(AssertUnwindSafe(|| (target.run)(&input)));
        IN_INPUT.store(false, Relaxed);
        if let (Some(a), Some(base)) = (alloc, baseline) {
            let peak = a.peak().saturating_sub(base) as u64;
            if report.max_peak_bytes.is_none_or(|m| peak > m) {
                report.max_peak_bytes = Some(peak);
                report.max_peak_input = Some(i);
            }
            if peak > budget_bytes {
                report.over_budget += 1;
                note(
                    &mut report,
                    format!("input {i}: peak {peak} bytes over budget"),
                );
            }
        }
        report.inputs += 1;
        let panics = PANICS.load(Relaxed) - panics_before;
        let dependency_panics = DEPENDENCY_PANICS.load(Relaxed) - dependency_panics_before;
        let caught_in_dependency = target.catches_dependency_panics
            && result.is_ok()
            && panics > 0
            && panics == dependency_panics;
        if caught_in_dependency {
            report.caught_dependency_panics += 1;
            LAST_PANIC.lock().unwrap_or_else(|p| p.into_inner()).take();
        } else if panics > 0 || result.is_err() {
            report.panics += 1;
            let last = LAST_PANIC.lock().unwrap_or_else(|p| p.into_inner()).take();
            note(
                &mut report,
                format!("input {i}: panic: {}", last.unwrap_or_default()),
            );
        }
        match result {
            Ok(Ok(())) => report.accepted += 1,
            Ok(Err(message)) => {
                report.rejected += 1;
                if message.trim().is_empty() {
                    report.empty_messages += 1;
                    note(&mut report, format!("input {i}: empty error message"));
                } else if let Some(name) = target.must_name {
                    if !message.contains(name) {
                        report.unnamed_errors += 1;
                        note(
                            &mut report,
                            format!("input {i}: error does not name {name:?}: {message}"),
                        );
                    }
                }
            }
            Err(_) => {}
        }
    }
    report.seconds = start.elapsed().as_secs_f64();
    report
}
