//! Fuzz target of the config parser and validator (see `pxpl5_tests::fuzzing`): the shipped
//! machine configs, mutated (bytes cut, repeated and spliced in, numbers replaced by extreme
//! ones, so every field takes arbitrary values), never make the loader panic; an error is a
//! proper report (it names the file, stays a few KB however big the input, and renders through
//! miette); an accepted config validates, prints and parses back to itself.

use miette::{GraphicalReportHandler, GraphicalTheme};
use proptest::prelude::*;
use pxpl5_config::{config_hash, parse_str, show, to_ron, validate};
use pxpl5_tests::fuzzing::{config, count, mutated, shipped};

/// Largest report of any error, in bytes: a window of a line, shortened words, at most 50
/// semantic problems of a few hundred chars each.
const MAX_REPORT_BYTES: usize = 64 * 1024;

fn check(name: &str, text: &str) -> Result<(), TestCaseError> {
    match parse_str(name, text) {
        Ok(cfg) => {
            prop_assert!(validate(&cfg).is_ok());
            let back = parse_str("to_ron", &to_ron(&cfg));
            prop_assert_eq!(back.as_ref().ok(), Some(&cfg), "to_ron does not parse back");
            let shown = parse_str("show", &show(&cfg));
            prop_assert_eq!(shown.as_ref().ok(), Some(&cfg), "show does not parse back");
            prop_assert_eq!(config_hash(&cfg).len(), 16);
        }
        Err(e) => {
            let shown = e.to_string();
            prop_assert!(shown.starts_with(name), "{}", shown);
            prop_assert!(shown.len() < MAX_REPORT_BYTES, "{} bytes", shown.len());
            let mut rendered = String::new();
            GraphicalReportHandler::new_themed(GraphicalTheme::unicode_nocolor())
                .render_report(&mut rendered, &e)
                .map_err(|_| TestCaseError::fail("miette cannot render the error"))?;
            prop_assert!(
                rendered.len() < MAX_REPORT_BYTES,
                "{} bytes",
                rendered.len()
            );
        }
    }
    Ok(())
}

proptest! {
    // About 0.1 ms a case in the test profile: 10,000 take about a second.
    #![proptest_config(config(10_000))]

    #[test]
    fn fuzz_config_files((name, text) in mutated(shipped("machine-configs"))) {
        check(&name, &text)?;
    }
}

/// The mutations reach every path: some configs stay valid (and reach the round trips), some
/// fail in the parser and some in the validator.
#[test]
fn fuzz_inputs_reach_every_path() {
    let strategy = mutated(shipped("machine-configs"));
    let outcome = |(name, text): &(String, String)| match parse_str(name, text) {
        Ok(_) => 0,
        Err(pxpl5_config::ConfigError::Semantic { .. }) => 1,
        Err(_) => 2,
    };
    let [ok, semantic, syntax] = [0, 1, 2].map(|k| count(&strategy, 500, |c| outcome(c) == k));
    assert!(
        ok > 25 && syntax > 25 && semantic > 25,
        "{ok} valid, {syntax} syntax, {semantic} semantic"
    );
}
