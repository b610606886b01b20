//! String formatting (`format!`, and the message of `panic!`-free macros that format): the
//! format string parsed when the program is loaded into literal pieces and holes ([`Fmt`]),
//! each hole naming an argument by position, by name or inline (`{x}`), with the specs the
//! interpreter supports: `?` (Debug), a width, an alignment and fill, `+`, `0` padding and a
//! precision. A spec outside these is refused at load with the hole's text.

use std::fmt::Write as _;

use crate::value::Value;

/// A parsed format string.
#[derive(Clone, Debug)]
pub(crate) struct Fmt {
    pub(crate) pieces: Vec<Piece>,
}

/// A piece of a format string.
#[derive(Clone, Debug)]
pub(crate) enum Piece {
    Text(String),
    Hole(Hole),
}

/// A hole: which argument, and how it prints.
#[derive(Clone, Debug)]
pub(crate) struct Hole {
    pub(crate) arg: ArgRef,
    pub(crate) debug: bool,
    pub(crate) width: Option<usize>,
    pub(crate) precision: Option<usize>,
    pub(crate) align: Option<char>,
    pub(crate) fill: char,
    pub(crate) plus: bool,
    pub(crate) zero: bool,
}

/// Which argument a hole prints.
#[derive(Clone, Debug)]
pub(crate) enum ArgRef {
    /// The next positional argument.
    Next,
    /// A positional argument.
    Index(usize),
    /// A named argument (`name = expr`) or, failing that, a variable in scope.
    Name(String),
}

/// Parses a format string; an error names what is not supported.
pub(crate) fn parse(s: &str) -> Result<Fmt, String> {
    let mut pieces = Vec::new();
    let mut text = String::new();
    let mut chars = s.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '{' if chars.peek() == Some(&'{') => {
                chars.next();
                text.push('{');
            }
            '}' if chars.peek() == Some(&'}') => {
                chars.next();
                text.push('}');
            }
            '{' => {
                let mut inner = String::new();
                loop {
                    match chars.next() {
                        Some('}') => break,
                        Some(c) => inner.push(c),
                        None => return Err(format!("`{{{inner}` is not closed")),
                    }
                }
                if !text.is_empty() {
                    pieces.push(Piece::Text(std::mem::take(&mut text)));
                }
                pieces.push(Piece::Hole(hole(&inner)?));
            }
            '}' => return Err("a `}` with no `{`: write `}}`".into()),
            c => text.push(c),
        }
    }
    if !text.is_empty() {
        pieces.push(Piece::Text(text));
    }
    Ok(Fmt { pieces })
}

fn hole(inner: &str) -> Result<Hole, String> {
    let (arg, spec) = match inner.split_once(':') {
        Some((a, s)) => (a.trim(), s),
        None => (inner.trim(), ""),
    };
    let arg = if arg.is_empty() {
        ArgRef::Next
    } else if let Ok(i) = arg.parse::<usize>() {
        ArgRef::Index(i)
    } else {
        ArgRef::Name(arg.to_string())
    };
    let mut h = Hole {
        arg,
        debug: false,
        width: None,
        precision: None,
        align: None,
        fill: ' ',
        plus: false,
        zero: false,
    };
    let mut spec: Vec<char> = spec.chars().collect();
    if spec.last() == Some(&'?') {
        h.debug = true;
        spec.pop();
    }
    let mut i = 0;
    if spec.len() >= 2 && matches!(spec[1], '<' | '>' | '^') {
        h.fill = spec[0];
        h.align = Some(spec[1]);
        i = 2;
    } else if spec.first().is_some_and(|c| matches!(c, '<' | '>' | '^')) {
        h.align = spec.first().copied();
        i = 1;
    }
    if spec.get(i) == Some(&'+') {
        h.plus = true;
        i += 1;
    }
    if spec.get(i) == Some(&'0') {
        h.zero = true;
        i += 1;
    }
    let digits = |i: &mut usize| {
        let start = *i;
        while spec.get(*i).is_some_and(char::is_ascii_digit) {
            *i += 1;
        }
        spec[start..*i]
            .iter()
            .collect::<String>()
            .parse::<usize>()
            .ok()
    };
    h.width = digits(&mut i);
    if spec.get(i) == Some(&'.') {
        i += 1;
        h.precision = digits(&mut i);
        if h.precision.is_none() {
            return Err(format!("the precision of `{{{inner}}}` is not a number"));
        }
    }
    if i != spec.len() {
        return Err(format!(
            "the format spec of `{{{inner}}}` is not supported when interpreted (`?`, fill and alignment, `+`, `0`, width and precision are)"
        ));
    }
    Ok(h)
}

/// Prints `value` into `out` as the hole says.
pub(crate) fn write_hole(out: &mut String, h: &Hole, value: &Value) {
    let body = match (value, h.precision, h.debug) {
        (Value::Float(x), Some(p), false) => {
            if h.plus {
                format!("{x:+.p$}")
            } else {
                format!("{x:.p$}")
            }
        }
        (Value::Float(x), Some(p), true) => format!("{x:.p$?}"),
        (Value::Str(s), Some(p), false) => s.chars().take(p).collect(),
        (Value::Int(i), _, _) if h.plus => format!("{i:+}"),
        (Value::Float(x), None, false) if h.plus => format!("{x:+}"),
        (v, _, true) => format!("{v:?}"),
        (v, _, false) => v.to_string(),
    };
    let Some(width) = h.width else {
        out.push_str(&body);
        return;
    };
    let len = body.chars().count();
    if len >= width {
        out.push_str(&body);
        return;
    }
    let pad = width - len;
    let numeric = matches!(value, Value::Int(_) | Value::Float(_));
    if h.zero && numeric {
        let (sign, digits) = match body.strip_prefix(['-', '+']) {
            Some(rest) => (&body[..1], rest),
            None => ("", body.as_str()),
        };
        let _ = write!(out, "{sign}{}{digits}", "0".repeat(pad));
        return;
    }
    let align = h.align.unwrap_or(if numeric { '>' } else { '<' });
    let fill = |n: usize| h.fill.to_string().repeat(n);
    match align {
        '>' => {
            out.push_str(&fill(pad));
            out.push_str(&body);
        }
        '^' => {
            out.push_str(&fill(pad / 2));
            out.push_str(&body);
            out.push_str(&fill(pad - pad / 2));
        }
        _ => {
            out.push_str(&body);
            out.push_str(&fill(pad));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn render(s: &str, args: &[Value]) -> String {
        let fmt = parse(s).expect("parses");
        let mut out = String::new();
        let mut next = 0;
        for p in &fmt.pieces {
            match p {
                Piece::Text(t) => out.push_str(t),
                Piece::Hole(h) => {
                    let i = match &h.arg {
                        ArgRef::Next => {
                            next += 1;
                            next - 1
                        }
                        ArgRef::Index(i) => *i,
                        ArgRef::Name(_) => 0,
                    };
                    write_hole(&mut out, h, &args[i]);
                }
            }
        }
        out
    }

    #[test]
    fn holes_print_as_rust_prints_them() {
        let x = Value::Float(1.23456);
        assert_eq!(
            render("{:.2}", std::slice::from_ref(&x)),
            format!("{:.2}", 1.23456)
        );
        assert_eq!(
            render("{:>8.1}|", std::slice::from_ref(&x)),
            format!("{:>8.1}|", 1.23456)
        );
        assert_eq!(render("{:05}", &[Value::Int(-42)]), format!("{:05}", -42));
        assert_eq!(render("{:?}", &[Value::str("a")]), format!("{:?}", "a"));
        assert_eq!(render("{{{}}}", &[Value::Int(1)]), "{1}");
        assert_eq!(
            render("{:*^7}", &[Value::str("ab")]),
            format!("{:*^7}", "ab")
        );
        assert!(parse("{:x}").is_err());
    }
}
