//! The Rust code of a body as the checker sees it: the assignments it can follow, the variables
//! a statement may change (forgotten), and the ways out of a body or loop it may take (`return`,
//! `break`, `continue`).

use proc_macro2::{Delimiter, TokenStream, TokenTree};

use super::body::BodyCompiler;
use crate::ir::{Exits, Op};
use crate::value::Sym;

impl BodyCompiler<'_, '_, '_> {
    /// A Rust statement: what it assigns the checker can follow, what it may change, and the ways
    /// out of the body or loop it may take.
    pub(super) fn rust(&mut self, tokens: &TokenStream, line: u32) {
        if mentions(tokens, "ctx") {
            self.note(line, "Rust code that uses `ctx` is not run: what it does to the tree, and its failures, are not explored");
        } else if has_question_mark(tokens) {
            self.note(
                line,
                "a `?` in Rust code is not run: the failure it may raise is not explored",
            );
        }
        let block: Option<syn::Block> = syn::parse2(quote_block(tokens)).ok();
        if let Some(block) = &block {
            for st in &block.stmts {
                match st {
                    syn::Stmt::Local(l) => {
                        let init = l.init.as_ref().map(|i| &*i.expr);
                        match (&l.pat, init) {
                            (syn::Pat::Ident(p), Some(e)) => {
                                let s = self.b.sym(&p.ident.to_string());
                                let v = self.b.lower(e);
                                self.emit(Op::Let(s, v), line);
                            }
                            (syn::Pat::Type(pt), Some(e)) => {
                                if let syn::Pat::Ident(p) = &*pt.pat {
                                    let s = self.b.sym(&p.ident.to_string());
                                    let v = self.b.lower(e);
                                    self.emit(Op::Let(s, v), line);
                                } else {
                                    self.forget_pattern(&l.pat, line);
                                }
                            }
                            _ => self.forget_pattern(&l.pat, line),
                        }
                    }
                    syn::Stmt::Expr(syn::Expr::Assign(a), _) => match &*a.left {
                        syn::Expr::Path(p) if p.path.get_ident().is_some() => {
                            let name = p
                                .path
                                .get_ident()
                                .map(ToString::to_string)
                                .unwrap_or_default();
                            let s = self.b.sym(&name);
                            let v = self.b.lower(&a.right);
                            self.emit(Op::Let(s, v), line);
                        }
                        _ => self.forget_assigned(tokens, line),
                    },
                    _ => self.forget_assigned(&quote::ToTokens::to_token_stream(st), line),
                }
            }
        } else {
            self.forget_assigned(tokens, line);
        }
        let mut exits = Exits::default();
        let (ret, brk, cont) = scan_exits(tokens);
        exits.ret = ret;
        if brk.is_some() || cont.is_some() {
            let want = |l: &Option<Option<String>>| l.clone();
            for (which, label) in [(0, want(&brk)), (1, want(&cont))] {
                let Some(label) = label else { continue };
                let frame = match &label {
                    Some(l) => self
                        .loops
                        .iter()
                        .rev()
                        .find(|f| f.label.as_deref() == Some(l)),
                    None => self.loops.last(),
                };
                if let Some(f) = frame {
                    if which == 0 {
                        exits.brk = Some((f.id, 0));
                    } else {
                        exits.cont = Some((f.id, f.test));
                    }
                }
            }
        }
        if exits.ret || exits.brk.is_some() || exits.cont.is_some() {
            let brk_loop = exits.brk.map(|(l, _)| l);
            let at = self.emit(Op::Exit(exits), line);
            if let Some(l) = brk_loop {
                if let Some(f) = self.loops.iter_mut().rev().find(|f| f.id == l) {
                    f.breaks.push(at);
                }
            }
        }
    }

    pub(super) fn forget_pattern(&mut self, pat: &syn::Pat, line: u32) {
        let mut names = Vec::new();
        idents(&quote::ToTokens::to_token_stream(pat), &mut names);
        let syms: Vec<Sym> = names.iter().map(|n| self.b.sym(n)).collect();
        if !syms.is_empty() {
            self.emit(Op::Forget(syms), line);
        }
    }

    /// Every variable a statement may assign (`x = …`, `x += …`, `&mut x`) becomes unknown.
    pub(super) fn forget_assigned(&mut self, tokens: &TokenStream, line: u32) {
        let mut names = Vec::new();
        assigned(tokens, &mut names);
        let known: Vec<Sym> = names
            .iter()
            .filter_map(|n| self.b.syms.get(n.as_str()).copied())
            .collect();
        if !known.is_empty() {
            self.emit(Op::Forget(known), line);
        }
    }
}

/// `{ tokens }` as a token stream.
fn quote_block(tokens: &TokenStream) -> TokenStream {
    let group = proc_macro2::Group::new(Delimiter::Brace, tokens.clone());
    TokenStream::from(TokenTree::Group(group))
}

/// Whether the tokens name `word` as an identifier.
fn mentions(tokens: &TokenStream, word: &str) -> bool {
    tokens.clone().into_iter().any(|tt| match tt {
        TokenTree::Ident(i) => i == word,
        TokenTree::Group(g) => mentions(&g.stream(), word),
        _ => false,
    })
}

fn has_question_mark(tokens: &TokenStream) -> bool {
    tokens.clone().into_iter().any(|tt| match tt {
        TokenTree::Punct(p) => p.as_char() == '?',
        TokenTree::Group(g) => has_question_mark(&g.stream()),
        _ => false,
    })
}

/// Identifiers in a pattern or place (the variables it binds or assigns).
pub(super) fn idents(tokens: &TokenStream, out: &mut Vec<String>) {
    for tt in tokens.clone() {
        match tt {
            TokenTree::Ident(i) => {
                let s = i.to_string();
                if !matches!(s.as_str(), "mut" | "ref" | "_") && !out.contains(&s) {
                    out.push(s);
                }
            }
            TokenTree::Group(g) => idents(&g.stream(), out),
            _ => {}
        }
    }
}

/// Variables a statement may assign: `x = …` (not `==`), `x op= …`, `&mut x`.
fn assigned(tokens: &TokenStream, out: &mut Vec<String>) {
    let tts: Vec<TokenTree> = tokens.clone().into_iter().collect();
    for (i, tt) in tts.iter().enumerate() {
        match tt {
            TokenTree::Group(g) => assigned(&g.stream(), out),
            TokenTree::Ident(id) => {
                let next = tts.get(i + 1);
                let after = tts.get(i + 2);
                let is_assign = match next {
                    Some(TokenTree::Punct(p)) if p.as_char() == '=' => {
                        !matches!(after, Some(TokenTree::Punct(q)) if q.as_char() == '=')
                            && p.spacing() == proc_macro2::Spacing::Alone
                    }
                    Some(TokenTree::Punct(p)) if "+-*/%^&|".contains(p.as_char()) => {
                        p.spacing() == proc_macro2::Spacing::Joint
                            && matches!(after, Some(TokenTree::Punct(q)) if q.as_char() == '=')
                    }
                    _ => false,
                };
                let mut_ref = i >= 2
                    && matches!(&tts[i - 1], TokenTree::Ident(m) if m == "mut")
                    && matches!(&tts[i - 2], TokenTree::Punct(p) if p.as_char() == '&');
                if (is_assign || mut_ref) && !out.contains(&id.to_string()) {
                    out.push(id.to_string());
                }
            }
            TokenTree::Punct(_) | TokenTree::Literal(_) => {}
        }
    }
}

/// Whether a Rust statement may `return`, and the labels of the `break` and `continue` it may
/// take out of the loops around it (`Some(None)`: unlabelled). A `break` or `continue` inside a
/// loop of the statement itself, or inside a closure, is that loop's.
#[allow(clippy::type_complexity)]
fn scan_exits(tokens: &TokenStream) -> (bool, Option<Option<String>>, Option<Option<String>>) {
    let mut ret = false;
    let mut brk = None;
    let mut cont = None;
    scan(tokens, false, &mut ret, &mut brk, &mut cont);
    (ret, brk, cont)
}

fn scan(
    tokens: &TokenStream,
    in_loop: bool,
    ret: &mut bool,
    brk: &mut Option<Option<String>>,
    cont: &mut Option<Option<String>>,
) {
    let tts: Vec<TokenTree> = tokens.clone().into_iter().collect();
    let mut loop_next = false;
    let mut closure = false;
    for (i, tt) in tts.iter().enumerate() {
        match tt {
            TokenTree::Ident(id) => {
                let s = id.to_string();
                match s.as_str() {
                    "loop" | "while" | "for" => loop_next = true,
                    "return" if !closure => *ret = true,
                    "break" | "continue" => {
                        let label = match tts.get(i + 1) {
                            Some(TokenTree::Punct(p)) if p.as_char() == '\'' => {
                                match tts.get(i + 2) {
                                    Some(TokenTree::Ident(l)) => Some(l.to_string()),
                                    _ => None,
                                }
                            }
                            _ => None,
                        };
                        // An unlabelled one inside a loop of the statement is that loop's.
                        if label.is_some() || !in_loop {
                            if s == "break" {
                                *brk = Some(label);
                            } else {
                                *cont = Some(label);
                            }
                        }
                    }
                    _ => {}
                }
            }
            TokenTree::Punct(p) if p.as_char() == '|' => closure = true,
            TokenTree::Group(g) => {
                let inner_loop = in_loop || (loop_next && g.delimiter() == Delimiter::Brace);
                if g.delimiter() == Delimiter::Brace {
                    loop_next = false;
                }
                if !closure {
                    scan(&g.stream(), inner_loop, ret, brk, cont);
                }
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(super) fn ts(src: &str) -> TokenStream {
        src.parse().expect("tokens")
    }

    #[test]
    pub(super) fn exits_of_a_rust_statement() {
        assert_eq!(scan_exits(&ts("if done() { return; }")), (true, None, None));
        assert_eq!(
            scan_exits(&ts("if x { break; }")),
            (false, Some(None), None)
        );
        // A loop of the statement's own keeps its break.
        assert_eq!(
            scan_exits(&ts("for i in v { if i { break; } }")),
            (false, None, None)
        );
        assert_eq!(
            scan_exits(&ts("while a { continue 'outer; }")),
            (false, None, Some(Some("outer".into())))
        );
        assert_eq!(
            scan_exits(&ts("let f = |x| { return x; };")),
            (false, None, None)
        );
    }

    #[test]
    pub(super) fn assigned_variables() {
        let mut out = Vec::new();
        assigned(&ts("x += 1; y = f(z == 2); g(&mut w);"), &mut out);
        assert_eq!(out, vec!["x", "y", "w"]);
    }
}
