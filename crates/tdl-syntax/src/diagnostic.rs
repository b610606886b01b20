//! Diagnostics: what the parser, the static diagnosis and the code generator report, and their text
//! rendering.
//!
//! A [`Diagnostic`] keeps the [`proc_macro2::Span`] it points at (so `tdl-macros` can turn it into a
//! spanned `syn::Error`) and the 1-based line and column of that span (so `tdl-build` and the CLI can
//! print `file:line:col` without the compiler). [`Diagnostic::render`] prints the rustc-like text form.
//! The parser lives in `parser.rs`, the static diagnosis in `diagnose.rs`.

use std::fmt::Write as _;

use proc_macro2::Span;

/// How bad a [`Diagnostic`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    /// The program is wrong; code must not be generated from it.
    Error,
    /// The program is valid but probably not what was meant.
    Warning,
}

impl Severity {
    /// The lowercase word used in rendered output: `error` or `warning`.
    pub fn as_str(self) -> &'static str {
        match self {
            Severity::Error => "error",
            Severity::Warning => "warning",
        }
    }
}

/// A 1-based line and 1-based column (counted in characters).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct LineCol {
    /// Line number, starting at 1.
    pub line: usize,
    /// Column number in characters, starting at 1.
    pub column: usize,
}

impl LineCol {
    fn start_of(span: Span) -> LineCol {
        let it = span.start();
        LineCol {
            line: it.line.max(1),
            column: it.column + 1,
        }
    }

    fn end_of(span: Span) -> LineCol {
        let it = span.end();
        LineCol {
            line: it.line.max(1),
            column: it.column + 1,
        }
    }
}

/// A secondary location attached to a [`Diagnostic`], such as "first defined here".
#[derive(Clone, Debug)]
pub struct Label {
    span: Span,
    start: LineCol,
    end: LineCol,
    message: String,
}

impl Label {
    /// The span the label points at.
    pub fn span(&self) -> Span {
        self.span
    }
    /// Where the label starts.
    pub fn start(&self) -> LineCol {
        self.start
    }
    /// What the label says about its location.
    pub fn message(&self) -> &str {
        &self.message
    }
}

/// One problem found in a TDL program.
///
/// Messages are lowercase with no trailing period and say what is wrong; the hint says what to do.
#[derive(Clone, Debug)]
pub struct Diagnostic {
    severity: Severity,
    span: Span,
    // Invariant: `start` and `end` are computed from `span`, with 1-based line and column.
    start: LineCol,
    end: LineCol,
    message: String,
    labels: Vec<Label>,
    hint: Option<String>,
}

impl Diagnostic {
    /// An error at `span`.
    pub fn error(span: Span, message: impl Into<String>) -> Diagnostic {
        Diagnostic::new(Severity::Error, span, message.into())
    }

    /// A warning at `span`.
    pub fn warning(span: Span, message: impl Into<String>) -> Diagnostic {
        Diagnostic::new(Severity::Warning, span, message.into())
    }

    fn new(severity: Severity, span: Span, message: String) -> Diagnostic {
        Diagnostic {
            severity,
            span,
            start: LineCol::start_of(span),
            end: LineCol::end_of(span),
            message,
            labels: Vec::new(),
            hint: None,
        }
    }

    /// Adds a hint saying what to do about the problem.
    #[must_use]
    pub fn with_hint(mut self, hint: impl Into<String>) -> Diagnostic {
        self.hint = Some(hint.into());
        self
    }

    /// Adds a secondary label at `span`.
    #[must_use]
    pub fn with_label(mut self, span: Span, message: impl Into<String>) -> Diagnostic {
        self.labels.push(Label {
            span,
            start: LineCol::start_of(span),
            end: LineCol::end_of(span),
            message: message.into(),
        });
        self
    }

    /// Error or warning.
    pub fn severity(&self) -> Severity {
        self.severity
    }
    /// True for [`Severity::Error`].
    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }
    /// The primary span, for `syn::Error::new(diag.span(), ...)` in the macro.
    pub fn span(&self) -> Span {
        self.span
    }
    /// Where the primary span starts (1-based line and column).
    pub fn start(&self) -> LineCol {
        self.start
    }
    /// 1-based line of the primary span.
    pub fn line(&self) -> usize {
        self.start.line
    }
    /// 1-based column of the primary span.
    pub fn column(&self) -> usize {
        self.start.column
    }
    /// What is wrong.
    pub fn message(&self) -> &str {
        &self.message
    }
    /// Secondary locations.
    pub fn labels(&self) -> &[Label] {
        &self.labels
    }
    /// What to do about it, if known.
    pub fn hint(&self) -> Option<&str> {
        self.hint.as_deref()
    }

    /// Renders the diagnostic as text: `file:line:col: error: message`, then the source line with a
    /// caret under the span, the labels, and `  = help: hint`.
    ///
    /// `source` is the text the spans point into; pass `None` when there is none (the macro), and
    /// only the header, labels and hint are printed.
    pub fn render(&self, file_name: &str, source: Option<&str>) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{file_name}:{}:{}: {}: {}",
            self.start.line,
            self.start.column,
            self.severity.as_str(),
            self.message
        );
        let gutter = [self.start.line]
            .into_iter()
            .chain(self.labels.iter().map(|it| it.start.line))
            .max()
            .unwrap_or(1)
            .to_string()
            .len();
        if let Some(source) = source {
            snippet(&mut out, source, gutter, self.start, self.end, '^', None);
            for label in &self.labels {
                snippet(
                    &mut out,
                    source,
                    gutter,
                    label.start,
                    label.end,
                    '-',
                    Some(&label.message),
                );
            }
        } else {
            for label in &self.labels {
                let _ = writeln!(
                    out,
                    "{:gutter$} = note: {}:{}: {}",
                    "", label.start.line, label.start.column, label.message
                );
            }
        }
        if let Some(hint) = &self.hint {
            let _ = writeln!(out, "{:gutter$} = help: {hint}", "");
        }
        out
    }
}

/// Renders every diagnostic of `diagnostics` with [`Diagnostic::render`], in order.
pub fn render_all(diagnostics: &[Diagnostic], file_name: &str, source: Option<&str>) -> String {
    diagnostics
        .iter()
        .map(|it| it.render(file_name, source))
        .collect::<Vec<_>>()
        .join("\n")
}

fn snippet(
    out: &mut String,
    source: &str,
    gutter: usize,
    start: LineCol,
    end: LineCol,
    mark: char,
    message: Option<&str>,
) {
    let Some(text) = source.lines().nth(start.line.saturating_sub(1)) else {
        return;
    };
    let text = text.replace('\t', " ");
    let n_chars = text.chars().count();
    let col = start.column.saturating_sub(1).min(n_chars);
    let width = if end.line == start.line && end.column > start.column {
        end.column - start.column
    } else {
        1
    };
    let _ = writeln!(out, "{:gutter$} |", "");
    let _ = writeln!(out, "{:>gutter$} | {}", start.line, text.trim_end());
    let marks: String = std::iter::repeat_n(mark, width).collect();
    match message {
        Some(message) => {
            let _ = writeln!(out, "{:gutter$} | {:col$}{marks} {message}", "", "");
        }
        None => {
            let _ = writeln!(out, "{:gutter$} | {:col$}{marks}", "", "");
        }
    }
}

impl Diagnostic {
    /// As a spanned `syn::Error` (for the `tdl!` macro): the message, then the hint as `help:`.
    pub fn to_syn_error(&self) -> syn::Error {
        let text = match &self.hint {
            Some(hint) => format!("{}\n  = help: {hint}", self.message),
            None => self.message.clone(),
        };
        syn::Error::new(self.span, text)
    }
}
