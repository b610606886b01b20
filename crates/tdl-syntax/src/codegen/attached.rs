//! Handlers and wiretaps attached from outside to a task (`handler h() handles E for T`,
//! `wiretap w() before T`): functions building a `tdl::Attached` or a `tdl::Tap` that read the
//! arguments of the node they recover or check, typed as that task's.

use proc_macro2::{Ident, TokenStream};
use quote::quote;

use super::{arg_pat, struct_ident_of};
use crate::ast::Task;

/// `wiretap w(args) before|after target { … }`: a function building the `tdl::Tap`, whose check
/// runs the body with the arguments of the node it checks (typed as `target`'s, as for an
/// attached handler).
pub(super) fn wiretap_fn(
    task: &Task,
    tap: &crate::ast::TapDecl,
    declared: Option<&[crate::ast::Arg]>,
    code: &TokenStream,
    reassigns: bool,
) -> TokenStream {
    let vis = &task.vis;
    let attrs: Vec<TokenStream> = crate::lint::rust_attrs(&task.attrs)
        .into_iter()
        .map(|(_, it)| it)
        .collect();
    let fn_name = &task.name;
    let name_str = task.name.to_string();
    let target_str = tap.target.to_string();
    let (target_name, read_args) = target_of(
        task,
        &tap.target,
        declared,
        quote!(::tdl::codegen::tapped_args),
    );
    let when = if tap.after {
        quote!(::tdl::TapWhen::After)
    } else {
        quote!(::tdl::TapWhen::Before)
    };
    let doc = format!(
        " Builds the TDL wiretap `{name_str}`, checking every `{target_str}` {}: give it to `Runtime::tap`.",
        if tap.after {
            "after it returned"
        } else {
            "before it starts"
        }
    );
    let allow = if reassigns {
        quote!(#[allow(unused_assignments)])
    } else {
        TokenStream::new()
    };
    quote! {
        #(#attrs)*
        #[doc = #doc]
        #allow
        #vis fn #fn_name() -> ::tdl::Tap {
            ::tdl::Tap::new(#target_name, #when, move |ctx| async move {
                #read_args
                #code
            })
        }
    }
}

/// What [`task_items`] built of a handler attached with `for`.
pub(super) struct AttachedParts {
    pub(super) exception: TokenStream,
    pub(super) code: TokenStream,
    pub(super) reassigns: bool,
    pub(super) prelude: TokenStream,
    pub(super) cells: TokenStream,
    pub(super) cell_clones: TokenStream,
    pub(super) modifiers: TokenStream,
}

/// `handler h(args) handles E for target`: a function building the `tdl::Attached` handler, which
/// reads its arguments from the node it recovers, an instance of `target` (typed by the
/// `TaskArgs` of `target`'s struct, so a mismatch is a compile error).
/// The handler `task` attached to `target`; `declared` holds the parameters of a target the
/// program declares `extern` (a task written elsewhere, which has no generated type to name).
pub(super) fn attached_handler(
    task: &Task,
    target: &Ident,
    declared: Option<&[crate::ast::Arg]>,
    parts: AttachedParts,
) -> TokenStream {
    let AttachedParts {
        exception,
        code,
        reassigns,
        prelude,
        cells,
        cell_clones,
        modifiers,
    } = parts;
    let vis = &task.vis;
    let attrs: Vec<TokenStream> = crate::lint::rust_attrs(&task.attrs)
        .into_iter()
        .map(|(_, it)| it)
        .collect();
    let fn_name = &task.name;
    let name_str = task.name.to_string();
    let target_str = target.to_string();
    let (target_name, read_args) = target_of(
        task,
        target,
        declared,
        quote!(::tdl::codegen::attached_args),
    );
    let doc = format!(
        " Builds the TDL handler `{name_str}`, attached to every `{target_str}`: give it to `Runtime::attach`."
    );
    let allow = if reassigns {
        quote!(#[allow(unused_assignments)])
    } else {
        TokenStream::new()
    };
    quote! {
        #(#attrs)*
        #[doc = #doc]
        #allow
        #vis fn #fn_name() -> ::tdl::Attached {
            #prelude
            #cells
            ::tdl::Attached::new(
                #target_name,
                ::tdl::Handler::new(#name_str, #exception, move |ctx| {
                    #cell_clones
                    async move {
                        #read_args
                        #code
                    }
                }) #modifiers,
            )
        }
    }
}

/// The target's name as the generated code gives it, and the statement that reads `task`'s
/// arguments from the node it recovers or checks with `reader` (`attached_args`, `tapped_args`):
/// typed by the generated tuple of a TDL task's arguments, or by the declared types of an extern
/// one's (`declared`); nothing to read when `task` takes no arguments.
fn target_of(
    task: &Task,
    target: &Ident,
    declared: Option<&[crate::ast::Arg]>,
    reader: TokenStream,
) -> (TokenStream, TokenStream) {
    let target_struct = struct_ident_of(target);
    let target_str = target.to_string();
    let name_str = task.name.to_string();
    let (target_name, target_args) = match declared {
        Some(args) => {
            let types: Vec<&syn::Type> = args.iter().map(|it| &it.ty).collect();
            (quote!(#target_str), quote!((#(#types,)*)))
        }
        None => (
            quote!(<#target_struct as ::tdl::codegen::TaskArgs>::NAME),
            quote!(<#target_struct as ::tdl::codegen::TaskArgs>::Args),
        ),
    };
    let read_args = if task.args.is_empty() {
        TokenStream::new()
    } else {
        let pats: Vec<TokenStream> = task.args.iter().map(arg_pat).collect();
        let types: Vec<&syn::Type> = task.args.iter().map(|it| &it.ty).collect();
        quote! {
            let (#(#pats,)*): (#(#types,)*) = #reader::<#target_args>(&ctx, #name_str, #target_str)?;
        }
    };
    (target_name, read_args)
}
