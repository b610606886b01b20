//! TDL's lints: every warning of the front end belongs to a class with a stable name,
//! `tdl::NAME`, and `#[allow(tdl::NAME)]` on a task or on a statement of a body accepts the
//! warnings of that class there (docs/language.md, "Accepting a warning").
//!
//! The parser reads the attributes (`lint_attrs`) and keeps each allowed lint as an
//! [`Allow`] of the file's [`Ast`](crate::Ast), with the source range it covers; once every
//! diagnostic of the file is known, [`apply`] drops the warnings an allow covers and reports each
//! allow that covered none, as rustc reports an unfulfilled `#[expect]`. The code generator
//! leaves the `tdl::` lints out of the attributes it copies (`rust_attrs`): rustc would reject a
//! lint of a tool it does not know.

use proc_macro2::{Span, TokenStream};
use quote::quote;
use syn::punctuated::Punctuated;
use syn::spanned::Spanned;
use syn::{Meta, Token};

use crate::ast::Allow;
use crate::diagnostic::{Diagnostic, LineCol};

/// A class of warnings, named `tdl::NAME` in `#[allow(…)]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Lint {
    /// `fail E;` that no handler of the program handles (docs/language.md, "Static checks", 3).
    UnhandledException,
    /// A task that spawns itself on every path through its body (docs/language.md, "Static
    /// checks", 4).
    UnboundedRecursion,
    /// A wait that never ends if some branches run (docs/language.md, "Static checks", 2).
    WaitMayNotEnd,
    /// `parallel` on a single spawn, where it has no effect.
    RedundantParallel,
    /// `fail;` without an exception, which no handler can match.
    FailWithoutException,
    /// A termination constraint on the task running the body (`self terminate …`).
    TerminateSelf,
    /// `priority` or `deny if busy` on a spawn that uses no resource.
    UnusedResourceOption,
    /// `#[allow(tdl::…)]` that accepts no warning.
    UnusedAllow,
}

impl Lint {
    /// Every lint, in the order the documentation lists them.
    pub const ALL: [Lint; 8] = [
        Lint::UnhandledException,
        Lint::UnboundedRecursion,
        Lint::WaitMayNotEnd,
        Lint::RedundantParallel,
        Lint::FailWithoutException,
        Lint::TerminateSelf,
        Lint::UnusedResourceOption,
        Lint::UnusedAllow,
    ];

    /// The name after `tdl::`: `unhandled_exception`, ….
    pub fn name(self) -> &'static str {
        match self {
            Lint::UnhandledException => "unhandled_exception",
            Lint::UnboundedRecursion => "unbounded_recursion",
            Lint::WaitMayNotEnd => "wait_may_not_end",
            Lint::RedundantParallel => "redundant_parallel",
            Lint::FailWithoutException => "fail_without_exception",
            Lint::TerminateSelf => "terminate_self",
            Lint::UnusedResourceOption => "unused_resource_option",
            Lint::UnusedAllow => "unused_allow",
        }
    }

    /// The lint named `name` (without `tdl::`).
    pub fn from_name(name: &str) -> Option<Lint> {
        Lint::ALL.into_iter().find(|it| it.name() == name)
    }
}

/// Every lint as `tdl::NAME`, joined by commas: for the hint of an unknown name.
fn names() -> String {
    Lint::ALL
        .iter()
        .map(|it| format!("tdl::{}", it.name()))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The attributes that set a lint's level.
const LEVELS: [&str; 5] = ["allow", "expect", "warn", "deny", "forbid"];

/// What the lint attributes among `attrs` say: the TDL lints allowed (each with the span of its
/// name), and the errors (an unknown name, a level other than `allow`).
pub(crate) struct LintAttrs {
    pub(crate) allowed: Vec<(Lint, Span)>,
    pub(crate) errors: Vec<Diagnostic>,
}

/// The `tdl::` paths of a lint-level attribute, with the other entries of its list; `None` when
/// the attribute sets no level or names no `tdl::` lint.
fn split(attr: &syn::Attribute) -> Option<(String, Vec<syn::Path>, Vec<Meta>)> {
    let level = LEVELS
        .into_iter()
        .find(|it| attr.path().is_ident(it))?
        .to_owned();
    let Meta::List(list) = &attr.meta else {
        return None;
    };
    let entries = list
        .parse_args_with(Punctuated::<Meta, Token![,]>::parse_terminated)
        .ok()?;
    let mut tdl = Vec::new();
    let mut rest = Vec::new();
    for entry in entries {
        match entry {
            Meta::Path(path) if path.segments.first().is_some_and(|it| it.ident == "tdl") => {
                tdl.push(path);
            }
            other => rest.push(other),
        }
    }
    (!tdl.is_empty()).then_some((level, tdl, rest))
}

/// True when `attr` names a `tdl::` lint.
pub(crate) fn is_tdl(attr: &syn::Attribute) -> bool {
    split(attr).is_some()
}

/// Reads the TDL lints of `attrs`.
pub(crate) fn lint_attrs(attrs: &[syn::Attribute]) -> LintAttrs {
    let mut out = LintAttrs {
        allowed: Vec::new(),
        errors: Vec::new(),
    };
    for attr in attrs {
        let Some((level, paths, _)) = split(attr) else {
            continue;
        };
        for path in paths {
            let text = quote!(#path).to_string().replace(' ', "");
            let Some(last) = path.segments.last() else {
                continue;
            };
            let span = last.ident.span();
            let lint = (path.segments.len() == 2 && path.leading_colon.is_none())
                .then(|| Lint::from_name(&last.ident.to_string()))
                .flatten();
            let Some(lint) = lint else {
                out.errors.push(
                    Diagnostic::error(span, format!("unknown TDL lint `{text}`"))
                        .with_hint(format!("the TDL lints are {}", names())),
                );
                continue;
            };
            if level != "allow" {
                let hint = if level == "expect" {
                    format!(
                        "write `#[allow({text})]`: an allow that accepts no warning is reported, as an unfulfilled `expect` is"
                    )
                } else {
                    format!(
                        "TDL warnings are on by default and never errors; `#[allow({text})]` accepts them here"
                    )
                };
                out.errors.push(
                    Diagnostic::error(
                        attr.path().span(),
                        format!("`#[{level}(…)]` does not take TDL lints: only `#[allow(…)]` does"),
                    )
                    .with_hint(hint),
                );
                continue;
            }
            out.allowed.push((lint, span));
        }
    }
    out
}

/// `attrs` without their `tdl::` lints, for the generated Rust, each with the span of its `#`: a
/// lint attribute that named only TDL lints is left out, one that also names Rust lints keeps
/// those.
pub(crate) fn rust_attrs(attrs: &[syn::Attribute]) -> Vec<(Span, TokenStream)> {
    let mut out = Vec::new();
    for attr in attrs {
        let span = attr.span();
        let Some((level, _, rest)) = split(attr) else {
            out.push((span, quote!(#attr)));
            continue;
        };
        let lints = rest
            .iter()
            .any(|it| !matches!(it, Meta::NameValue(nv) if nv.path.is_ident("reason")));
        if lints {
            let level = syn::Ident::new(&level, attr.path().span());
            out.push((span, quote!(#[#level(#(#rest),*)])));
        }
    }
    out
}

/// Errors for the TDL lints on an item that takes none (`what`: "an exception", …).
pub(crate) fn misplaced(attrs: &[syn::Attribute], what: &str) -> Vec<Diagnostic> {
    attrs
        .iter()
        .filter(|it| is_tdl(it))
        .map(|attr| {
            Diagnostic::error(
                attr.span(),
                format!("a TDL lint cannot be allowed on {what}"),
            )
            .with_hint(
                "put `#[allow(tdl::…)]` on the task or on the statement of a body the warning points into",
            )
        })
        .collect()
}

/// The allow that covers a warning of `lint` at `at`: of those covering it, the innermost (the
/// one starting last).
fn covering(allows: &[Allow], lint: Lint, at: LineCol) -> Option<usize> {
    allows
        .iter()
        .enumerate()
        .filter(|(_, it)| {
            it.lint == lint && LineCol::start_of(it.from) <= at && at <= LineCol::end_of(it.to)
        })
        .max_by_key(|(_, it)| LineCol::start_of(it.from))
        .map(|(i, _)| i)
}

/// Drops from `diags`, the diagnostics of one file, the warnings an allow of `allows` (that
/// file's) accepts, and reports each allow that accepts none: a warning of
/// [`Lint::UnusedAllow`], which an allow can accept too. With errors in the file, unused allows
/// are not reported: checks that the errors cut short may have missed what they accept.
pub(crate) fn apply(allows: &[Allow], diags: &mut Vec<Diagnostic>) {
    if allows.is_empty() {
        return;
    }
    let mut used = vec![false; allows.len()];
    // Whether `diag` stays: no allow accepts it (the innermost one that does is used).
    let keep = |diag: &Diagnostic, used: &mut [bool]| -> bool {
        let Some(lint) = diag.lint() else {
            return true;
        };
        match covering(allows, lint, diag.start()) {
            Some(i) => {
                used[i] = true;
                false
            }
            None => true,
        }
    };
    diags.retain(|it| keep(it, &mut used));
    if diags.iter().any(Diagnostic::is_error) {
        return;
    }
    let mut unused: Vec<Diagnostic> = Vec::new();
    for (allow, _) in allows
        .iter()
        .zip(&used)
        .filter(|(it, used)| !**used && it.lint != Lint::UnusedAllow)
    {
        let name = allow.lint.name();
        unused.push(
            Diagnostic::warning(
                Lint::UnusedAllow,
                allow.span,
                format!("`#[allow(tdl::{name})]` accepts no warning"),
            )
            .with_hint(format!(
                "it covers the task or the statement it is written on, and no `tdl::{name}` \
                 warning points into that: remove it, or move it onto the statement or the \
                 task the warning points into"
            )),
        );
    }
    unused.retain(|it| keep(it, &mut used));
    diags.extend(unused);
    diags.sort_by_key(|it| (it.start(), it.severity()));
}
