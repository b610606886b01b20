//! Unit tests for time literals: suffixed numbers, `H:M:S`, expressions and times of day.

use syn::parse::Parser;

use super::{decimal_to_nanos, format_nanos, parse_rel_time, parse_time_of_day};
use crate::ast::RelTime;

fn rel(src: &str) -> Result<u64, String> {
    match parse_rel_time.parse_str(src) {
        Ok(RelTime::Nanos(nanos)) => Ok(nanos),
        Ok(RelTime::Seconds(expr)) => {
            Err(format!("expr {}", quote::ToTokens::to_token_stream(&expr)))
        }
        Err(err) => Err(err.to_string()),
    }
}

#[test]
fn suffixed_literals() {
    assert_eq!(rel("30s"), Ok(30_000_000_000));
    assert_eq!(rel("1.5s"), Ok(1_500_000_000));
    assert_eq!(rel("200ms"), Ok(200_000_000));
    assert_eq!(rel("2min"), Ok(120_000_000_000));
    assert_eq!(rel("1h"), Ok(3_600_000_000_000));
    assert_eq!(rel("250us"), Ok(250_000));
    assert_eq!(rel("7ns"), Ok(7));
    assert_eq!(
        rel("0.5"),
        Ok(500_000_000),
        "unsuffixed numbers are seconds"
    );
    assert_eq!(rel("1_000ms"), Ok(1_000_000_000));
}

#[test]
fn hms_relative_times() {
    assert_eq!(rel("0:0:30.0"), Ok(30_000_000_000));
    assert_eq!(rel("0:0:1.5"), Ok(1_500_000_000));
    assert_eq!(rel("1:2:3"), Ok(3_723_000_000_000));
    // Relative H:M:S has no range checks (docs/semantics.md, "Time").
    assert_eq!(rel("0:90:0"), Ok(5_400_000_000_000));
    assert!(rel("0:30").is_err_and(|it| it.contains("all three parts")));
}

#[test]
fn expressions_and_errors() {
    assert_eq!(
        rel("(period_s / 2.0)"),
        Err("expr period_s / 2.0".to_owned())
    );
    assert!(rel("30 parsecs").is_err());
    assert!(rel("3days").is_err_and(|it| it.contains("unknown time unit `days`")));
    assert!(rel("\"soon\"").is_err_and(|it| it.contains("expected a time")));
    assert!(rel("99999999999999999999999s").is_err_and(|it| it.contains("too large")));
}

#[test]
fn decimal_conversion_is_exact() {
    assert_eq!(decimal_to_nanos("0.1", 1_000_000_000), Some(100_000_000));
    assert_eq!(decimal_to_nanos("2.5e-3", 1_000_000_000), Some(2_500_000));
    assert_eq!(decimal_to_nanos("1e3", 1_000_000), Some(1_000_000_000));
    assert_eq!(decimal_to_nanos("0.0000000001", 1_000_000_000), Some(0));
    assert_eq!(decimal_to_nanos("1.2.3", 1), None);
    assert_eq!(decimal_to_nanos("", 1), None);
    assert_eq!(decimal_to_nanos("1e999999", 1), None);
}

#[test]
fn time_of_day_range_checks() {
    let mut diags = Vec::new();
    let ok = (|input: syn::parse::ParseStream| parse_time_of_day(input, &mut diags))
        .parse_str("13:05:07.25");
    let ok = ok.map(|it| (it.hour, it.minute, it.second, it.nanos));
    assert_eq!(ok.ok(), Some((13, 5, 7, 250_000_000)));
    assert!(diags.is_empty());

    let mut diags = Vec::new();
    let bad = (|input: syn::parse::ParseStream| parse_time_of_day(input, &mut diags))
        .parse_str("24:60:00");
    assert!(bad.is_ok(), "a bad time of day is reported, not fatal");
    let messages: Vec<&str> = diags.iter().map(|it| it.message()).collect();
    assert_eq!(
        messages,
        ["invalid time of day: hour 24 is not in 0-23, minute 60 is not in 0-59"]
    );
}

#[test]
fn formats_nanos_in_exact_units() {
    assert_eq!(format_nanos(30_000_000_000), "30s");
    assert_eq!(format_nanos(1_500_000_000), "1500ms");
    assert_eq!(format_nanos(250_000), "250us");
    assert_eq!(format_nanos(7), "7ns");
    assert_eq!(format_nanos(0), "0s");
}
