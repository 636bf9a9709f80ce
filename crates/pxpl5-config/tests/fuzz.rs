//! Fuzz target of the config parser and validator (see `pxpl5_tests::fuzzing`): the shipped
//! machine configs, mutated (bytes cut, repeated and spliced in, numbers replaced by extreme
//! ones, so every field takes arbitrary values), never make the loader panic; an error is a
//! proper report (it names the file, stays a few KB however big the input, and renders through
//! miette); an accepted config validates, prints and parses back to itself.

use proptest::prelude::*;
use pxpl5_config::{config_hash, parse_str, show, to_ron, validate};
use pxpl5_tests::fuzzing::{config, count, loaded, mutated, shipped};

fn check(name: &str, text: &str) -> Result<(), TestCaseError> {
    if let Some(cfg) = loaded(name, parse_str(name, text))? {
        prop_assert!(validate(&cfg).is_ok());
        let back = parse_str("to_ron", &to_ron(&cfg));
        prop_assert_eq!(back.as_ref().ok(), Some(&cfg), "to_ron does not parse back");
        let shown = parse_str("show", &show(&cfg));
        prop_assert_eq!(shown.as_ref().ok(), Some(&cfg), "show does not parse back");
        prop_assert_eq!(config_hash(&cfg).len(), 16);
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
