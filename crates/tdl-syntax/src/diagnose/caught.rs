//! A handler body that reads the exception it caught by a name it never bound: older programs
//! wrote `exception` (a binding the generated code used to make); today the body names it with
//! `handles E as name` (docs/language.md). Without this check the mistake surfaces as rustc's
//! "cannot find value `exception`" in generated code.

use proc_macro2::{Span, TokenStream, TokenTree};
use quote::ToTokens;

use crate::ast::{Stmt, Task, TaskKind};
use crate::diagnostic::Diagnostic;
use crate::hir::{Visit, walk_stmt};

/// The name older handler bodies read the caught exception by.
const OLD_NAME: &str = "exception";

/// Reports a handler whose body reads `exception` without binding it.
pub(super) fn check(task: &Task, diags: &mut Vec<Diagnostic>) {
    if task.kind != TaskKind::Handler || task.caught.is_some() {
        return;
    }
    let mut scan = Scan::default();
    scan.block(&task.body);
    let (Some(at), false) = (scan.used, scan.bound) else {
        return;
    };
    let handles = task
        .handles
        .as_ref()
        .map_or_else(|| "E".to_owned(), ToString::to_string);
    diags.push(
        Diagnostic::error(at, format!("`{OLD_NAME}` is not bound in the body of handler `{}`", task.name))
            .with_hint(format!(
                "name the caught exception in the header: `handler {}(…) handles {handles} as {OLD_NAME} {{ … }}`",
                task.name
            )),
    );
}

/// Where the body's Rust code reads `exception`, and whether it binds that name itself.
#[derive(Default)]
struct Scan {
    used: Option<Span>,
    bound: bool,
}

impl Scan {
    /// Looks at each `exception` of `tokens` that is a value (not a field `x.exception`, a path
    /// segment `m::exception` or a field name `exception: v`), and at each `let [mut] exception`.
    fn tokens(&mut self, tokens: TokenStream) {
        let tts: Vec<TokenTree> = tokens.into_iter().collect();
        let punct = |tt: Option<&TokenTree>, c: char| matches!(tt, Some(TokenTree::Punct(p)) if p.as_char() == c);
        let ident = |tt: Option<&TokenTree>, word: &str| matches!(tt, Some(TokenTree::Ident(i)) if i == word);
        for (i, tt) in tts.iter().enumerate() {
            match tt {
                TokenTree::Ident(it) if it == OLD_NAME => {
                    let before = i.checked_sub(1).and_then(|b| tts.get(b));
                    let before2 = i.checked_sub(2).and_then(|b| tts.get(b));
                    let after = tts.get(i + 1);
                    let field = punct(before, '.') || punct(before, ':');
                    let field_name = punct(after, ':') && !punct(tts.get(i + 2), ':');
                    if ident(before, "let") || (ident(before, "mut") && ident(before2, "let")) {
                        self.bound = true;
                    } else if !field && !field_name && self.used.is_none() {
                        self.used = Some(it.span());
                    }
                }
                TokenTree::Group(group) => self.tokens(group.stream()),
                _ => {}
            }
        }
    }
}

impl<'a> Visit<'a> for Scan {
    fn stmt(&mut self, stmt: &'a Stmt) {
        match stmt {
            Stmt::Rust(it) => self.tokens(it.tokens.clone()),
            Stmt::Spawn(it) => {
                for arg in &it.args {
                    self.tokens(arg.to_token_stream());
                }
            }
            Stmt::Bind(it) => self.tokens(it.expr.to_token_stream()),
            Stmt::Fail(it) => {
                for field in &it.fields {
                    self.tokens(field.to_token_stream());
                }
            }
            Stmt::Retry(it) => {
                for arg in it.args.iter().flatten() {
                    self.tokens(arg.to_token_stream());
                }
            }
            _ => walk_stmt(self, stmt),
        }
    }

    fn code(&mut self, code: TokenStream) {
        self.tokens(code);
    }
}
