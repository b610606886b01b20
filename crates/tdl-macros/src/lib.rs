//! `tdl!`: TDL task definitions with Rust bodies, compiled at macro-expansion time into Rust
//! calling the `tcm` runtime. Use it through the `tdl` crate, which re-exports it with the runtime.
//!
//! Architecture Invariant: no logic here. Parsing, checks, code generation and the error stubs
//! all live in `tdl-syntax` (`expand_macro`), shared with `tdl-build` and the `tdl` CLI.

/// Compiles TDL task definitions into Rust items (see `docs/language.md`).
///
/// Every diagnostic becomes a spanned compile error; the declared tasks are still emitted as
/// stubs, so one mistake shows one error.
#[proc_macro]
pub fn tdl(input: proc_macro::TokenStream) -> proc_macro::TokenStream {
    tdl_syntax::expand_macro(input.into()).into()
}
