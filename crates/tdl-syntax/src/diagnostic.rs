//! Diagnostics: what the parser, the static diagnosis and the code generator report, and their text
//! rendering.
//!
//! A [`Diagnostic`] keeps the [`proc_macro2::Span`] it points at (so `tdl-macros` can turn it into a
//! spanned `syn::Error`) and the 1-based line and column of that span (so `tdl-build` and the CLI can
//! print `file:line:col` without the compiler). [`Diagnostic::render`] prints rustc's text form with
//! `annotate-snippets`, rustc's own renderer ([`Diagnostic::render_styled`] with its colours).
//! The parser lives in `parser.rs`, the static diagnosis in `diagnose.rs`.

use proc_macro2::Span;

pub(crate) use crate::lint::Lint;

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
    pub(crate) fn start_of(span: Span) -> LineCol {
        let it = span.start();
        LineCol {
            line: it.line.max(1),
            column: it.column + 1,
        }
    }

    pub(crate) fn end_of(span: Span) -> LineCol {
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
    /// The file it points into, when not the diagnostic's own.
    file: Option<String>,
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
    /// The file the label points into, when it is another than the diagnostic's.
    pub fn file(&self) -> Option<&str> {
        self.file.as_deref()
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
    /// The lint a warning belongs to; `None` for an error.
    lint: Option<Lint>,
}

impl Diagnostic {
    /// An error at `span`.
    pub fn error(span: Span, message: impl Into<String>) -> Diagnostic {
        Diagnostic::new(Severity::Error, span, message.into())
    }

    /// A warning of the class `lint` at `span`: `#[allow(tdl::NAME)]` with the lint's name, on
    /// the statement or the task it is in, accepts it there.
    pub fn warning(lint: Lint, span: Span, message: impl Into<String>) -> Diagnostic {
        let mut it = Diagnostic::new(Severity::Warning, span, message.into());
        it.lint = Some(lint);
        it
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
            lint: None,
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
            file: None,
            span,
            start: LineCol::start_of(span),
            end: LineCol::end_of(span),
            message: message.into(),
        });
        self
    }

    /// Adds a secondary label at `span` in another file of the program, `file`: rendered as a
    /// note naming the file, line and column.
    #[must_use]
    pub fn with_label_in(
        mut self,
        file: &str,
        span: Span,
        message: impl Into<String>,
    ) -> Diagnostic {
        self.labels.push(Label {
            file: Some(file.to_owned()),
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
    /// The lint of a warning (its class, which `#[allow(tdl::NAME)]` names); `None` for an
    /// error.
    pub fn lint(&self) -> Option<Lint> {
        self.lint
    }

    /// Renders the diagnostic as plain text, as rustc does (with `annotate-snippets`, rustc's own
    /// renderer): `error: message`, ` --> file:line:col`, the source lines with the span
    /// underlined and the labels, a `= note:` naming a warning's lint, then `= help: hint`.
    ///
    /// `source` is the text the spans point into; pass `None` when there is none (the macro), and
    /// only the header, the location, the labels' locations and the hint are printed.
    pub fn render(&self, file_name: &str, source: Option<&str>) -> String {
        self.render_with(file_name, source, false)
    }

    /// As [`Diagnostic::render`], with the terminal colours rustc uses (ANSI escapes): for output
    /// to a terminal.
    pub fn render_styled(&self, file_name: &str, source: Option<&str>) -> String {
        self.render_with(file_name, source, true)
    }

    fn render_with(&self, file_name: &str, source: Option<&str>, styled: bool) -> String {
        use annotate_snippets::{AnnotationKind, Level, Origin, Renderer, Snippet};

        let level = match self.severity {
            Severity::Error => Level::ERROR,
            Severity::Warning => Level::WARNING,
        };
        // Labels in another file, and every label when there is no source, are notes.
        let notes: Vec<String> = self
            .labels
            .iter()
            .filter(|it| source.is_none() || it.file.is_some())
            .map(|it| match &it.file {
                Some(file) => format!(
                    "{}: {file}:{}:{}",
                    it.message, it.start.line, it.start.column
                ),
                None => format!("{}:{}: {}", it.start.line, it.start.column, it.message),
            })
            .collect();
        let group = level.primary_title(self.message.as_str());
        let mut group = match source {
            Some(source) => {
                let mut snippet = Snippet::source(source)
                    .path(file_name)
                    .fold(true)
                    .annotation(
                        AnnotationKind::Primary.span(byte_range(source, self.start, self.end)),
                    );
                for label in self.labels.iter().filter(|it| it.file.is_none()) {
                    snippet = snippet.annotation(
                        AnnotationKind::Context
                            .span(byte_range(source, label.start, label.end))
                            .label(label.message.as_str()),
                    );
                }
                group.element(snippet)
            }
            None => group.element(
                Origin::path(file_name)
                    .line(self.start.line)
                    .char_column(self.start.column),
            ),
        };
        for note in &notes {
            group = group.element(Level::NOTE.message(note.as_str()));
        }
        let allow = self.lint.filter(|it| *it != Lint::UnusedAllow).map(|lint| {
            format!(
                "`#[allow(tdl::{})]` on the statement or on its task accepts this warning there",
                lint.name()
            )
        });
        if let Some(allow) = &allow {
            group = group.element(Level::NOTE.message(allow.as_str()));
        }
        if let Some(hint) = &self.hint {
            group = group.element(Level::HELP.message(hint.as_str()));
        }
        let renderer = if styled {
            Renderer::styled()
        } else {
            Renderer::plain()
        };
        let mut out = renderer.render(&[group]);
        out.push('\n');
        out
    }
}

/// Renders every diagnostic of `diagnostics` with [`Diagnostic::render`], in order, separated by
/// blank lines.
pub fn render_all(diagnostics: &[Diagnostic], file_name: &str, source: Option<&str>) -> String {
    diagnostics
        .iter()
        .map(|it| it.render(file_name, source))
        .collect::<Vec<_>>()
        .join("\n")
}

/// As [`render_all`], with colours (see [`Diagnostic::render_styled`]).
pub fn render_all_styled(
    diagnostics: &[Diagnostic],
    file_name: &str,
    source: Option<&str>,
) -> String {
    diagnostics
        .iter()
        .map(|it| it.render_styled(file_name, source))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The byte offset in `source` of a 1-based line and 1-based character column, clamped to the
/// line's end (and to the source's end for a line past it).
fn byte_offset(source: &str, at: LineCol) -> usize {
    let mut line_start = 0;
    for _ in 1..at.line {
        match source[line_start..].find('\n') {
            Some(i) => line_start += i + 1,
            None => return source.len(),
        }
    }
    let line = &source[line_start..];
    let line = &line[..line.find('\n').unwrap_or(line.len())];
    let column = line
        .char_indices()
        .nth(at.column.saturating_sub(1))
        .map_or(line.len(), |(i, _)| i);
    line_start + column
}

/// The byte range of a span, at least one character wide so that the caret shows.
fn byte_range(source: &str, start: LineCol, end: LineCol) -> std::ops::Range<usize> {
    let from = byte_offset(source, start);
    let to = byte_offset(source, end).max(from);
    if to > from {
        return from..to;
    }
    let next = source[from..].chars().next().map_or(0, char::len_utf8);
    from..from + next
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
