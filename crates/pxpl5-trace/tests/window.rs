//! Tests of `TraceWindow` and `parse_time`: the syntax users type after `--trace-window`, its exact
//! decimal arithmetic and its error messages.

use pxpl5_sim::Tick;
use pxpl5_trace::{TimeErrorKind, TraceWindow, WindowParseError, format_time, parse_time};

fn window(s: &str) -> TraceWindow {
    s.parse()
        .unwrap_or_else(|e| panic!("`{s}` should parse: {e}"))
}

fn ps(s: &str) -> u64 {
    parse_time(s)
        .unwrap_or_else(|e| panic!("`{s}` should parse: {e}"))
        .as_ps()
}

#[test]
fn every_unit() {
    assert_eq!(ps("7ps"), 7);
    assert_eq!(ps("7ns"), 7_000);
    assert_eq!(ps("7us"), 7_000_000);
    assert_eq!(ps("7ms"), 7_000_000_000);
    assert_eq!(ps("7s"), 7_000_000_000_000);
}

#[test]
fn decimals_are_exact() {
    assert_eq!(ps("1.5us"), 1_500_000);
    assert_eq!(ps("0.025us"), 25_000);
    assert_eq!(ps("0.000001us"), 1);
    assert_eq!(ps("0.000000000001s"), 1);
    assert_eq!(ps("2.5ms"), 2_500_000_000);
    // 0.1 and 0.2 have no exact binary value; an f64 route would give 300000.00000000006 or so.
    assert_eq!(ps("0.3us"), 300_000);
    assert_eq!(ps("0.1ns") + ps("0.2ns"), ps("0.3ns"));
    // Trailing zeros beyond a picosecond are harmless: they add no value.
    assert_eq!(ps("1.000000ps"), 1);
    assert_eq!(
        ps("1.5000000000000000000000000000000000000000000000us"),
        1_500_000
    );
    assert_eq!(ps("007ns"), 7_000);
}

#[test]
fn zero_needs_no_unit() {
    assert_eq!(ps("0"), 0);
    assert_eq!(ps("0.000"), 0);
    assert_eq!(ps("0ms"), 0);
}

#[test]
fn largest_time() {
    assert_eq!(ps("18446744073709551615ps"), u64::MAX);
    assert_eq!(ps("18446744.073709551615s"), u64::MAX);
    for too_big in [
        "18446744073709551616ps",
        "18446745s",
        "99999999999999999999999999999s",
    ] {
        let err = parse_time(too_big).unwrap_err();
        assert_eq!(err.kind, TimeErrorKind::TooLarge, "{too_big}");
    }
}

#[test]
fn sub_picosecond_is_rejected() {
    for s in ["0.0000001ns", "0.5ps", "1.0001ns", "0.0000000000001s"] {
        let err = parse_time(s).unwrap_err();
        assert_eq!(err.kind, TimeErrorKind::SubPicosecond, "{s}");
        assert!(err.to_string().contains("finer than a picosecond"), "{err}");
    }
}

#[test]
fn malformed_times_say_what_was_expected() {
    let cases = [
        ("", TimeErrorKind::BadNumber),
        ("ms", TimeErrorKind::BadNumber),
        (".5us", TimeErrorKind::BadNumber),
        ("1.us", TimeErrorKind::BadNumber),
        ("1..2us", TimeErrorKind::BadNumber),
        ("-1us", TimeErrorKind::BadNumber),
        ("+1us", TimeErrorKind::BadNumber),
        ("1e3ns", TimeErrorKind::UnknownUnit("e3ns".into())),
        ("5", TimeErrorKind::MissingUnit),
        ("0.5", TimeErrorKind::MissingUnit),
        ("3 us", TimeErrorKind::UnknownUnit(" us".into())),
        ("3min", TimeErrorKind::UnknownUnit("min".into())),
        ("3µs", TimeErrorKind::UnknownUnit("µs".into())),
        ("3US", TimeErrorKind::UnknownUnit("US".into())),
    ];
    for (text, kind) in cases {
        let err = parse_time(text).unwrap_err();
        assert_eq!(err.kind, kind, "`{text}`");
    }
    assert_eq!(
        parse_time("1.us").unwrap_err().to_string(),
        "`1.us` is not a time: expected a decimal number followed by a unit, such as `25000ps`, \
         `1.5us` or `2ms`"
    );
    assert_eq!(
        parse_time("5").unwrap_err().to_string(),
        "`5` has no unit: expected one of ps, ns, us, ms or s after the number"
    );
    assert_eq!(
        parse_time("3min").unwrap_err().to_string(),
        "`3min` has unknown unit `min`: expected one of ps, ns, us, ms or s"
    );
}

#[test]
fn windows() {
    assert_eq!(
        window("0..2ms"),
        TraceWindow {
            start: Tick(0),
            end: Tick(2_000_000_000)
        }
    );
    assert_eq!(
        window("1.5us..3us"),
        TraceWindow {
            start: Tick(1_500_000),
            end: Tick(3_000_000)
        }
    );
    assert_eq!(
        window("..1ms"),
        TraceWindow {
            start: Tick(0),
            end: Tick(1_000_000_000)
        }
    );
    assert_eq!(
        window("2ms.."),
        TraceWindow {
            start: Tick(2_000_000_000),
            end: Tick::MAX
        }
    );
    assert_eq!(window(".."), TraceWindow::all());
    assert_eq!(window(" 1ns .. 2ns "), window("1ns..2ns"));
    assert_eq!(TraceWindow::default(), TraceWindow::all());
}

#[test]
fn windows_are_half_open() {
    let w = window("1ns..2ns");
    assert!(!w.contains(Tick(999)));
    assert!(w.contains(Tick(1_000)));
    assert!(w.contains(Tick(1_999)));
    assert!(!w.contains(Tick(2_000)));
    assert!(!w.is_open_ended());
    assert!(TraceWindow::all().is_open_ended());
}

#[test]
fn bad_windows() {
    for text in ["", "2ms", "0-2ms", "0..1ms..2ms", "0...2ms"] {
        let err = TraceWindow::parse(text).unwrap_err();
        // "0...2ms" splits as "0" and ".2ms": a bad end rather than a missing range.
        if text == "0...2ms" {
            assert!(matches!(err, WindowParseError::End(_)), "{text}: {err:?}");
        } else {
            assert!(
                matches!(err, WindowParseError::NotARange(_)),
                "{text}: {err:?}"
            );
            assert!(err.to_string().contains("expected START..END"), "{err}");
        }
    }
    let err = TraceWindow::parse("2ms..1ms").unwrap_err();
    assert_eq!(
        err.to_string(),
        "time window `2ms..1ms` is empty: expected its start to be before its end"
    );
    assert!(matches!(
        TraceWindow::parse("1ms..1ms"),
        Err(WindowParseError::Empty { .. })
    ));
    assert!(matches!(
        TraceWindow::parse("..0"),
        Err(WindowParseError::Empty { .. })
    ));
    let err = TraceWindow::parse("1xs..2ms").unwrap_err();
    assert!(matches!(err, WindowParseError::Start(_)));
    assert!(
        err.to_string()
            .starts_with("bad window start: `1xs` has unknown unit")
    );
    let err = TraceWindow::parse("0..0.0000001ns").unwrap_err();
    assert!(matches!(err, WindowParseError::End(_)));
    assert!(std::error::Error::source(&err).is_some());
}

#[test]
fn display_round_trips() {
    for text in [
        "0..2ms",
        "1.5us..3us",
        "..1ms",
        "2ms..",
        "..",
        "1ps..1s",
        "25ns..75001ps",
    ] {
        let w = window(text);
        let shown = w.to_string();
        assert_eq!(window(&shown), w, "{text} -> {shown}");
    }
    assert_eq!(window("1.5us..3us").to_string(), "1500ns..3us");
    assert_eq!(TraceWindow::all().to_string(), "0..");
    assert_eq!(format_time(Tick(75_001)), "75001ps");
}

/// Every short string over an alphabet of the syntax's characters (and a few others) either parses
/// or is an error: never a panic.
#[test]
fn no_input_panics() {
    let alphabet = ['0', '9', '.', 'u', 's', 'm', 'p', 'µ', ' ', '-'];
    let mut strings = vec![String::new()];
    for _ in 0..4 {
        let longer: Vec<String> = strings
            .iter()
            .flat_map(|s| alphabet.iter().map(move |c| format!("{s}{c}")))
            .collect();
        strings.extend(longer);
    }
    for s in &strings {
        let _ = parse_time(s);
        let _ = TraceWindow::parse(s);
        let _ = TraceWindow::parse(&format!("{s}..{s}"));
    }
}
