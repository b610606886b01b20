//! TDL's constraint keywords: one- and two-word phrases, joined forms and synonyms.
//!
//! Constraint words are matched case-insensitively, and an identifier may join several words with
//! any number of underscores (`expand_first`, `EXPAND__FIRST`, `expandfirst`, `disable_until`),
//! as in TDL 1.5 (docs/semantics.md, "Words"). Old TCA words are synonyms: `planning` is `expansion`,
//! `achievement` is `execution`; the paper's `max`, `activations` and `triggers` are accepted too.
//! The statement and item keywords (`spawn`, `with`, `goal`, ...) are plain lowercase Rust-style
//! identifiers and are matched in `parser.rs`.

use proc_macro2::Span;
use syn::buffer::Cursor;
use syn::parse::ParseStream;

/// Every word a joined keyword identifier may be split into, after synonyms are applied.
const VOCABULARY: &[&str] = &[
    "achievement",
    "activate",
    "activates",
    "activation",
    "activations",
    "active",
    "after",
    "approval",
    "at",
    "busy",
    "change",
    "completed",
    "delay",
    "deny",
    "disable",
    "enabled",
    "exception",
    "execution",
    "expand",
    "expansion",
    "external",
    "failed",
    "first",
    "for",
    "handler",
    "handling",
    "if",
    "in",
    "initial",
    "invariant",
    "max",
    "maximum",
    "name",
    "of",
    "on",
    "outcome",
    "parallel",
    "parent",
    "pause",
    "period",
    "persistent",
    "planning",
    "priority",
    "propagate",
    "sequential",
    "serial",
    "skip",
    "succeeded",
    "terminate",
    "terminated",
    "trigger",
    "triggers",
    "until",
    "uses",
    "wait",
    "when",
    "while",
    "within",
];

/// Maps a synonym to its canonical word.
fn canonical(word: &'static str) -> &'static str {
    match word {
        "planning" => "expansion",
        "achievement" => "execution",
        "max" => "maximum",
        "activates" | "activation" | "activations" => "activate",
        "triggers" => "trigger",
        other => other,
    }
}

/// Identifier text with underscores removed and ASCII letters lowercased.
fn normalize(text: &str) -> String {
    text.chars()
        .filter(|it| *it != '_')
        .map(|it| it.to_ascii_lowercase())
        .collect()
}

/// Splits a normalised identifier into vocabulary words, or `None` when it is not made of them.
pub(crate) fn split(norm: &str) -> Option<Vec<&'static str>> {
    if norm.is_empty() {
        return Some(Vec::new());
    }
    // Longest word first, so `activate` wins over `active` + `ate` (which fails anyway).
    let mut candidates: Vec<&'static str> = VOCABULARY
        .iter()
        .copied()
        .filter(|it| norm.starts_with(it))
        .collect();
    candidates.sort_by_key(|it| std::cmp::Reverse(it.len()));
    for word in candidates {
        if let Some(mut rest) = norm.get(word.len()..).and_then(split) {
            rest.insert(0, canonical(word));
            return Some(rest);
        }
    }
    None
}

/// One keyword word at the parse position.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Word {
    /// The canonical word, or `None` when the identifier is not a keyword.
    pub(crate) text: Option<&'static str>,
    /// True when this word is the last of its identifier, so parsing may stop after it.
    pub(crate) ident_end: bool,
    /// Span of the identifier holding the word.
    pub(crate) span: Span,
}

/// The words of the next `max_idents` identifiers (stopping at the first non-identifier).
pub(crate) fn peek_words(cursor: Cursor<'_>, max_idents: usize) -> Vec<Word> {
    let mut out = Vec::new();
    let mut cursor = cursor;
    for _ in 0..max_idents {
        let Some((ident, next)) = cursor.ident() else {
            break;
        };
        let span = ident.span();
        match split(&normalize(&ident.to_string())) {
            Some(words) if !words.is_empty() => {
                let n = words.len();
                for (i, word) in words.into_iter().enumerate() {
                    out.push(Word {
                        text: Some(word),
                        ident_end: i + 1 == n,
                        span,
                    });
                }
            }
            _ => out.push(Word {
                text: None,
                ident_end: true,
                span,
            }),
        }
        cursor = next;
    }
    out
}

/// True when the next words are exactly `words` (ending on an identifier boundary).
pub(crate) fn peek_phrase(input: ParseStream, words: &[&str]) -> bool {
    let found = peek_words(input.cursor(), words.len());
    found.len() >= words.len()
        && words
            .iter()
            .zip(&found)
            .all(|(want, got)| got.text == Some(*want))
        && found
            .get(words.len().saturating_sub(1))
            .is_some_and(|it| it.ident_end)
}

/// Consumes the identifiers holding the next `n_words` words, which must end on an identifier
/// boundary. Returns the span of the first identifier.
pub(crate) fn take_words(input: ParseStream, n_words: usize) -> syn::Result<Span> {
    let found = peek_words(input.cursor(), n_words);
    let Some(last) = found.get(n_words.saturating_sub(1)) else {
        return Err(input.error("expected a keyword"));
    };
    if !last.ident_end {
        return Err(syn::Error::new(
            last.span,
            "this keyword joins words that do not belong together here",
        ));
    }
    let n_idents = found.iter().take(n_words).filter(|it| it.ident_end).count();
    let span = input.span();
    input.step(|cursor| {
        let mut rest = *cursor;
        for _ in 0..n_idents {
            match rest.ident() {
                Some((_, next)) => rest = next,
                None => return Err(cursor.error("expected a keyword")),
            }
        }
        Ok(((), rest))
    })?;
    Ok(span)
}

/// Consumes `words` or fails with "expected `words`".
pub(crate) fn expect_phrase(input: ParseStream, words: &[&str]) -> syn::Result<Span> {
    if peek_phrase(input, words) {
        take_words(input, words.len())
    } else {
        Err(input.error(format!("expected `{}`", words.join(" "))))
    }
}

/// True when `word` starts a constraint, so `IDENT word` begins a constraint statement.
pub(crate) fn starts_constraint(word: &str) -> bool {
    matches!(
        word,
        "expand"
            | "delay"
            | "sequential"
            | "serial"
            | "parallel"
            | "wait"
            | "outcome"
            | "propagate"
            | "approval"
            | "disable"
            | "terminate"
            | "activate"
            | "maximum"
            | "period"
            | "exception"
            | "handler"
            | "on"
            | "name"
            | "parent"
            | "uses"
            | "priority"
            | "deny"
            | "skip"
            | "invariant"
            | "pause"
    )
}

#[cfg(test)]
mod tests;
