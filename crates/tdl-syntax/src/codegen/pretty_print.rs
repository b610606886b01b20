//! Printing generated code: [`pretty`] formats it as readable Rust and turns the source markers
//! that `body.rs` puts before each body statement into comments naming the `.tdl` line; the raw
//! fallback drops them.

use std::collections::BTreeSet;

use proc_macro2::TokenStream;

use super::body;

/// Formats generated items as readable Rust (`prettyplease`); falls back to the raw tokens if
/// they do not parse as a file. The source markers of [`compile_str`] and [`compile_program`]
/// become comments: every line generated for a body statement ends with `// file.tdl:line`,
/// the statement's line, so that the snippet rustc shows with an error in generated code names
/// the `.tdl` line (a line inside a string literal spanning lines is left as it is).
///
/// [`compile_str`]: super::compile_str
/// [`compile_program`]: super::compile_program
pub fn pretty(tokens: &TokenStream) -> String {
    match syn::parse2::<syn::File>(tokens.clone()) {
        Ok(file) => source_comments(&prettyplease::unparse(&file)),
        Err(_) => strip_source_markers(tokens.clone()).to_string(),
    }
}

/// Replaces the source-marker lines of pretty-printed code by a comment at the end of each line
/// they cover. A marker covers the lines after it, up to the next marker at the same or a lower
/// indentation or the first line indented less (the end of its block); markers of nested
/// statements cover their own lines. `__tdl_source!();` covers code of the generator's own.
fn source_comments(text: &str) -> String {
    let prefix = format!("{}!(", body::SOURCE_MARKER);
    if !text.contains(&prefix) {
        return text.to_owned();
    }
    let (ends_inside, starts_inside) = lines_inside_literals(text);
    // The markers in force: (indentation, source).
    let mut stack: Vec<(usize, Option<&str>)> = Vec::new();
    let mut out = String::with_capacity(text.len() * 2);
    // A marker the printer wrapped over several lines (a long file name in a nested statement):
    // its indentation and argument, until its `);`.
    let mut wrapped: Option<(usize, Option<&str>)> = None;
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let trimmed = line.trim_start();
        let indent = line.len() - trimmed.len();
        // A line that starts inside a literal says nothing of blocks.
        let continues = starts_inside.contains(&n);
        if let Some((at, arg)) = wrapped {
            if trimmed == ");" {
                wrapped = None;
                stack.retain(|(i, _)| *i < at);
                let source = arg
                    .map(|a| a.trim_end_matches(','))
                    .and_then(|a| a.strip_prefix('"'))
                    .and_then(|it| it.strip_suffix('"'));
                stack.push((at, source));
            } else {
                wrapped = Some((at, arg.or(Some(trimmed))));
            }
            continue;
        }
        if trimmed == prefix && !continues {
            wrapped = Some((indent, None));
            continue;
        }
        let marker = trimmed
            .strip_prefix(&prefix)
            .and_then(|rest| rest.strip_suffix(");"))
            .filter(|_| !continues);
        if let Some(arg) = marker {
            stack.retain(|(at, _)| *at < indent);
            let source = arg.strip_prefix('"').and_then(|it| it.strip_suffix('"'));
            stack.push((indent, source));
            continue;
        }
        if !trimmed.is_empty() && !continues {
            stack.retain(|(at, _)| *at <= indent);
        }
        out.push_str(line);
        if let Some((_, Some(source))) = stack.last() {
            if !trimmed.is_empty() && !ends_inside.contains(&n) {
                out.push_str(" // ");
                out.push_str(source);
            }
        }
        out.push('\n');
    }
    out
}

/// The (1-based) lines of `text` that end inside a literal (a comment appended to them would
/// change the literal), and those that start inside one.
fn lines_inside_literals(text: &str) -> (BTreeSet<usize>, BTreeSet<usize>) {
    fn walk(tokens: TokenStream, out: &mut (BTreeSet<usize>, BTreeSet<usize>)) {
        for token in tokens {
            match token {
                proc_macro2::TokenTree::Group(group) => walk(group.stream(), out),
                proc_macro2::TokenTree::Literal(lit) => {
                    let (start, end) = (lit.span().start().line, lit.span().end().line);
                    out.0.extend(start..end);
                    out.1.extend(start + 1..=end);
                }
                _ => {}
            }
        }
    }
    let mut out = (BTreeSet::new(), BTreeSet::new());
    match text.parse::<TokenStream>() {
        Ok(tokens) => walk(tokens, &mut out),
        // Not expected for prettyplease's output; then no line is safe.
        Err(_) => out.0.extend(1..=text.lines().count()),
    }
    out
}

/// `tokens` without source markers (for the raw fallback of [`pretty`]).
fn strip_source_markers(tokens: TokenStream) -> TokenStream {
    use proc_macro2::TokenTree;
    let tokens: Vec<TokenTree> = tokens.into_iter().collect();
    let mut out = TokenStream::new();
    let mut i = 0;
    while i < tokens.len() {
        let is_marker = matches!(&tokens[i], TokenTree::Ident(id) if id == body::SOURCE_MARKER)
            && matches!(tokens.get(i + 1), Some(TokenTree::Punct(p)) if p.as_char() == '!');
        if is_marker {
            // `__tdl_source ! ( .. ) ;`
            i += 4;
            continue;
        }
        match &tokens[i] {
            TokenTree::Group(group) => {
                let mut inner = proc_macro2::Group::new(
                    group.delimiter(),
                    strip_source_markers(group.stream()),
                );
                inner.set_span(group.span());
                out.extend([TokenTree::Group(inner)]);
            }
            other => out.extend([other.clone()]),
        }
        i += 1;
    }
    out
}
