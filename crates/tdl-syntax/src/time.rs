//! Time literals in constraints: relative times and absolute times of day.
//!
//! Relative times are Rust-friendly suffixed literals (`30s`, `1.5s`, `200ms`, `2min`), TDL's
//! `H:M:S[.frac]` (`0:0:30.0`, no range checks), an unsuffixed number of seconds (`0.5`), or a
//! parenthesised Rust expression in seconds (`(period_s / 2.0)`), as in TDL 1.2 (docs/semantics.md, "Time").
//! Absolute times of day are `H:M:S[.frac]` with H in 0-23 and M, S in 0-59.
//! Constants are converted to nanoseconds exactly, with integer arithmetic.

use proc_macro2::{Delimiter, Span};
use syn::parse::ParseStream;
use syn::{Lit, Token};

use crate::ast::{RelTime, TimeOfDay};
use crate::diagnostic::Diagnostic;
use crate::parser::{parse_group_as, take_group};

const NANOS_PER_SECOND: u64 = 1_000_000_000;

/// Hint for errors in times.
pub(crate) const TIME_HINT: &str = "write a time such as `30s`, `1.5s`, `200ms`, `2min`, \
     `0:0:30.0`, or a parenthesised expression in seconds such as `(period_s / 2.0)`; units are \
     `h`, `min`, `s`, `ms`, `us` and `ns`; a time of day reads `13:00:00`";

/// Nanoseconds in one unit of a time suffix, or `None` for an unknown suffix.
pub(crate) fn unit_nanos(suffix: &str) -> Option<u64> {
    match suffix {
        "" | "s" => Some(NANOS_PER_SECOND),
        "ms" => Some(1_000_000),
        "us" => Some(1_000),
        "ns" => Some(1),
        "min" => Some(60 * NANOS_PER_SECOND),
        "h" => Some(3_600 * NANOS_PER_SECOND),
        _ => None,
    }
}

/// Converts a decimal number (`30`, `1.5`, `2.5e-3`, as `syn`'s `base10_digits`) times `unit`
/// nanoseconds to whole nanoseconds, rounding down; `None` when malformed or beyond `u64`.
pub(crate) fn decimal_to_nanos(digits: &str, unit: u64) -> Option<u64> {
    let (mantissa, exponent) = match digits.find(['e', 'E']) {
        Some(at) => (
            digits.get(..at)?,
            digits.get(at + 1..)?.parse::<i32>().ok()?,
        ),
        None => (digits, 0),
    };
    let (int_part, frac_part) = match mantissa.split_once('.') {
        Some((int_part, frac_part)) => (int_part, frac_part),
        None => (mantissa, ""),
    };
    let all_digits = format!("{int_part}{frac_part}");
    if all_digits.is_empty() || !all_digits.bytes().all(|it| it.is_ascii_digit()) {
        return None;
    }
    // value = all_digits * 10^(exponent - frac_len) * unit
    let scale = exponent.checked_sub(i32::try_from(frac_part.len()).ok()?)?;
    let significant = all_digits.trim_start_matches('0');
    if significant.len() > 38 {
        return None;
    }
    let mut value = if significant.is_empty() {
        0u128
    } else {
        significant.parse::<u128>().ok()?
    };
    value = value.checked_mul(u128::from(unit))?;
    if scale >= 0 {
        for _ in 0..scale {
            value = value.checked_mul(10)?;
        }
    } else {
        for _ in 0..scale.unsigned_abs() {
            value /= 10;
            if value == 0 {
                break;
            }
        }
    }
    u64::try_from(value).ok()
}

/// True when the input starts like `H:` of an `H:M:S` time.
fn peek_hms(input: ParseStream) -> bool {
    input.peek(syn::LitInt) && input.peek2(Token![:]) && !input.peek2(Token![::])
}

/// The three numbers of `H:M:S[.frac]`: hours, minutes and the seconds digits.
struct Hms {
    hours: u64,
    minutes: u64,
    seconds: String,
    span: Span,
}

fn parse_hms(input: ParseStream) -> syn::Result<Hms> {
    let span = input.span();
    let hours: syn::LitInt = input.parse()?;
    input.parse::<Token![:]>()?;
    let minutes: syn::LitInt = input.parse()?;
    if !input.peek(Token![:]) {
        return Err(syn::Error::new(
            minutes.span(),
            "a time of the form `H:M:S` needs all three parts",
        ));
    }
    input.parse::<Token![:]>()?;
    let seconds = match input.parse::<Lit>()? {
        Lit::Int(it) if it.suffix().is_empty() => it.base10_digits().to_owned(),
        Lit::Float(it) if it.suffix().is_empty() => it.base10_digits().to_owned(),
        other => return Err(syn::Error::new(other.span(), "expected seconds in `H:M:S`")),
    };
    let number = |it: &syn::LitInt| -> syn::Result<u64> {
        if !it.suffix().is_empty() {
            return Err(syn::Error::new(
                it.span(),
                "expected a plain number in `H:M:S`",
            ));
        }
        it.base10_parse::<u64>()
    };
    Ok(Hms {
        hours: number(&hours)?,
        minutes: number(&minutes)?,
        seconds,
        span,
    })
}

/// Parses a relative time.
pub(crate) fn parse_rel_time(input: ParseStream) -> syn::Result<RelTime> {
    if input.peek(syn::token::Paren) {
        let group = take_group(input, Delimiter::Parenthesis, "`(`")?;
        return parse_group_as::<syn::Expr>(group).map(RelTime::Seconds);
    }
    if peek_hms(input) {
        let hms = parse_hms(input)?;
        let nanos = hms
            .hours
            .checked_mul(60)
            .and_then(|it| it.checked_add(hms.minutes))
            .and_then(|it| it.checked_mul(60 * NANOS_PER_SECOND))
            .and_then(|it| it.checked_add(decimal_to_nanos(&hms.seconds, NANOS_PER_SECOND)?));
        return match nanos {
            Some(nanos) => Ok(RelTime::Nanos(nanos)),
            None => Err(syn::Error::new(hms.span, "time is too large")),
        };
    }
    let (digits, suffix, span) = match input.parse::<Lit>() {
        Ok(Lit::Int(it)) => (
            it.base10_digits().to_owned(),
            it.suffix().to_owned(),
            it.span(),
        ),
        Ok(Lit::Float(it)) => (
            it.base10_digits().to_owned(),
            it.suffix().to_owned(),
            it.span(),
        ),
        Ok(other) => return Err(syn::Error::new(other.span(), "expected a time")),
        Err(err) => return Err(syn::Error::new(err.span(), "expected a time")),
    };
    let Some(unit) = unit_nanos(&suffix) else {
        return Err(syn::Error::new(
            span,
            format!("unknown time unit `{suffix}`"),
        ));
    };
    match decimal_to_nanos(&digits, unit) {
        Some(nanos) => Ok(RelTime::Nanos(nanos)),
        None => Err(syn::Error::new(span, "time is too large")),
    }
}

/// True when the input starts like an absolute time of day.
pub(crate) fn peek_time_of_day(input: ParseStream) -> bool {
    input.peek(syn::LitInt) || input.peek(syn::LitFloat)
}

/// Parses an absolute time of day; out-of-range parts become errors in `diags` (the time is still
/// returned, clamped, so parsing goes on).
pub(crate) fn parse_time_of_day(
    input: ParseStream,
    diags: &mut Vec<Diagnostic>,
) -> syn::Result<TimeOfDay> {
    if !peek_hms(input) {
        return Err(
            input.error("expected an absolute time of day `H:M:S[.frac]` such as `13:00:00`")
        );
    }
    let hms = parse_hms(input)?;
    let seconds_nanos = decimal_to_nanos(&hms.seconds, NANOS_PER_SECOND).unwrap_or(u64::MAX);
    let seconds = seconds_nanos / NANOS_PER_SECOND;
    let mut bad = Vec::new();
    if hms.hours > 23 {
        bad.push(format!("hour {} is not in 0-23", hms.hours));
    }
    if hms.minutes > 59 {
        bad.push(format!("minute {} is not in 0-59", hms.minutes));
    }
    if seconds > 59 {
        bad.push(format!("second {} is not in 0-59", hms.seconds));
    }
    if !bad.is_empty() {
        diags.push(
            Diagnostic::error(hms.span, format!("invalid time of day: {}", bad.join(", ")))
                .with_hint("an absolute time is a time of day `H:M:S` with H in 0-23 and M, S in 0-59; for a delay use `in` or `for`"),
        );
    }
    Ok(TimeOfDay {
        hour: u8::try_from(hms.hours.min(23)).unwrap_or(23),
        minute: u8::try_from(hms.minutes.min(59)).unwrap_or(59),
        second: u8::try_from(seconds.min(59)).unwrap_or(59),
        nanos: u32::try_from(seconds_nanos % NANOS_PER_SECOND).unwrap_or(0),
    })
}

/// Renders a constant relative time in the shortest exact unit, e.g. `30s`, `1500ms`.
pub fn format_nanos(nanos: u64) -> String {
    const UNITS: [(u64, &str); 4] = [
        (NANOS_PER_SECOND, "s"),
        (1_000_000, "ms"),
        (1_000, "us"),
        (1, "ns"),
    ];
    for (unit, suffix) in UNITS {
        if nanos % unit == 0 {
            return format!("{}{suffix}", nanos / unit);
        }
    }
    format!("{nanos}ns")
}

#[cfg(test)]
mod tests;
