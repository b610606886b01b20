//! Patterns of the interpreted subset (`let`, `match`, `if let`, `for`, closure parameters):
//! bindings, `_`, literals and ranges of them, tuples, variants (`Some(x)`, `Ended::Failed(f)`,
//! `None`), records (`E { a, b: p, .. }`), `|`, and constants of the registry. A binding is
//! declared in the current scope as it is lowered.

use std::sync::Arc;

use syn::spanned::Spanned;

use super::Lower;
use super::expr::path_text;
use crate::builtin;
use crate::ir::Pat;
use crate::value::Value;

impl Lower<'_, '_> {
    /// The pattern `p`, its bindings declared.
    pub(crate) fn pat(&mut self, p: &syn::Pat) -> Pat {
        use syn::Pat as P;
        match p {
            P::Wild(_) | P::Rest(_) => Pat::Wild,
            P::Ident(id) => {
                let sub = id.subpat.as_ref().map(|(_, sub)| Box::new(self.pat(sub)));
                let name = id.ident.to_string();
                // A constant of the registry (an upper-case name), compared, not bound.
                if sub.is_none() && id.mutability.is_none() {
                    if let Some(v) = self.registry.constants.get(&name) {
                        return Pat::Const(v.clone());
                    }
                    if name == "None" {
                        return Pat::Variant(None, Arc::from("None"), Vec::new());
                    }
                }
                Pat::Bind(self.declare(&name), sub)
            }
            P::Lit(l) => match self.lit_value(&l.lit) {
                Some(v) => Pat::Lit(v),
                None => Pat::Wild,
            },
            P::Range(r) => {
                let bound = |me: &mut Self, e: &Option<Box<syn::Expr>>| {
                    e.as_ref().and_then(|e| me.const_value(e))
                };
                let lo = bound(self, &r.start);
                let hi = bound(self, &r.end);
                Pat::Range(lo, hi, matches!(r.limits, syn::RangeLimits::Closed(_)))
            }
            P::Paren(p) => self.pat(&p.pat),
            P::Reference(r) => self.pat(&r.pat),
            P::Type(t) => self.pat(&t.pat),
            P::Tuple(t) => Pat::Tuple(t.elems.iter().map(|it| self.pat(it)).collect()),
            P::Slice(s) => Pat::Tuple(s.elems.iter().map(|it| self.pat(it)).collect()),
            P::TupleStruct(ts) => {
                let (ty, name) = split_variant(&ts.path);
                let fields = ts.elems.iter().map(|it| self.pat(it)).collect();
                Pat::Variant(ty, name, fields)
            }
            P::Path(pp) => {
                let text = path_text(&pp.path);
                if let Some(v) = self.registry.constants.get(&text) {
                    return Pat::Const(v.clone());
                }
                let (ty, name) = split_variant(&pp.path);
                Pat::Variant(ty, name, Vec::new())
            }
            P::Struct(s) => {
                let name = path_text(&s.path);
                let fields = s
                    .fields
                    .iter()
                    .filter_map(|f| match &f.member {
                        syn::Member::Named(n) => Some((Arc::from(n.to_string()), self.pat(&f.pat))),
                        syn::Member::Unnamed(_) => {
                            self.unsupported(f.span(), "a numbered field in a pattern");
                            None
                        }
                    })
                    .collect();
                let name = name.rsplit("::").next().unwrap_or_default().to_string();
                Pat::Record(Arc::from(name.as_str()), fields)
            }
            P::Or(o) => {
                // Every alternative binds the same names, in the same slots.
                let mark = self.scope_len();
                let mut alts = Vec::new();
                for (i, case) in o.cases.iter().enumerate() {
                    alts.push(self.pat(case));
                    if i == 0 {
                        self.reuse = self.declared_since(mark);
                    }
                }
                self.reuse.clear();
                Pat::Or(alts)
            }
            other => {
                self.unsupported(other.span(), "this pattern");
                Pat::Wild
            }
        }
    }

    fn lit_value(&mut self, lit: &syn::Lit) -> Option<Value> {
        match self.expr(&syn::Expr::Lit(syn::ExprLit {
            attrs: Vec::new(),
            lit: lit.clone(),
        })) {
            crate::ir::Ex::Lit(v) => Some(v),
            _ => None,
        }
    }

    /// A constant expression in a pattern: a literal, negated or not, or a constant.
    fn const_value(&mut self, e: &syn::Expr) -> Option<Value> {
        match e {
            syn::Expr::Lit(l) => self.lit_value(&l.lit),
            syn::Expr::Unary(u) if matches!(u.op, syn::UnOp::Neg(_)) => {
                match self.const_value(&u.expr)? {
                    Value::Int(i) => Some(Value::Int(-i)),
                    Value::Float(x) => Some(Value::Float(-x)),
                    _ => None,
                }
            }
            syn::Expr::Path(p) => {
                let text = path_text(&p.path);
                self.registry
                    .constants
                    .get(&text)
                    .cloned()
                    .or_else(|| builtin::constant(&text))
            }
            other => {
                self.unsupported(other.span(), "this bound of a range pattern");
                None
            }
        }
    }
}

/// `Enum::Variant` as (enum, variant); `Variant` alone as (none, variant).
fn split_variant(path: &syn::Path) -> (Option<Arc<str>>, Arc<str>) {
    let segs: Vec<String> = path.segments.iter().map(|s| s.ident.to_string()).collect();
    match segs.as_slice() {
        [] => (None, Arc::from("")),
        [one] => (None, Arc::from(one.as_str())),
        [.., ty, name] => (Some(Arc::from(ty.as_str())), Arc::from(name.as_str())),
    }
}
