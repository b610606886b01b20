//! `extern goal|command name(args) [-> T];`: the signature of a task implemented outside TDL.

use proc_macro2::Ident;
use syn::Token;
use syn::ext::IdentExt;
use syn::parse::ParseStream;

use super::{Cx, signature};
use crate::ast::{ExternDecl, Item, TaskKind};

/// After `extern`: the kind, the name, the signature and `;`.
pub(super) fn extern_decl(
    input: ParseStream,
    cx: &mut Cx,
    attrs: Vec<syn::Attribute>,
) -> syn::Result<Item> {
    let keyword = input.call(Ident::parse_any)?;
    let kind = match keyword.to_string().as_str() {
        "goal" => TaskKind::Goal,
        "command" => TaskKind::Command,
        _ => {
            return Err(syn::Error::new(
                keyword.span(),
                "expected `goal` or `command` after `extern`: a task implemented elsewhere is one of them",
            ));
        }
    };
    let name: Ident = input.parse()?;
    let (args, result) = signature(input, cx)?;
    if !input.peek(Token![;]) {
        return Err(input.error(
            "expected `;` after an extern task's signature: it has no body (`extern command dig(x: f64) -> f64;`)",
        ));
    }
    input.parse::<Token![;]>()?;
    let span = name.span();
    Ok(Item::Extern(ExternDecl {
        attrs,
        kind,
        name,
        args,
        result,
        span,
    }))
}
