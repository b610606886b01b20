//! Parsing the declarations that are no tasks: `resource`, `state` and `environment`
//! (docs/semantics.md, "Resources" and "State and conditions").

use super::*;

/// `resource name(capacity) [pending N];` (docs/semantics.md, "Resources").
pub(super) fn resource(
    input: ParseStream,
    attrs: Vec<syn::Attribute>,
    persistent: bool,
    keyword_span: Span,
    cx: &mut Cx,
) -> syn::Result<Item> {
    not_persistent(
        cx,
        persistent,
        keyword_span,
        "a resource",
        "remove `persistent`",
    );
    let name: Ident = input.parse()?;
    let group = take_group(
        input,
        Delimiter::Parenthesis,
        "`(` and the resource's capacity, as in `resource arm(2);`",
    )?;
    let capacity: syn::LitInt = parse_group_as(group)?;
    let pending = if input.peek(syn::Ident) && input.fork().call(Ident::parse_any)? == "pending" {
        input.call(Ident::parse_any)?;
        Some(input.parse::<syn::LitInt>()?)
    } else {
        None
    };
    if !input.peek(Token![;]) {
        return Err(input.error(
            "expected `;` or `pending N` after the resource's capacity, as in \
             `resource arm(2) pending 4;`",
        ));
    }
    input.parse::<Token![;]>()?;
    let span = name.span();
    Ok(Item::Resource(ResourceDecl {
        attrs,
        name,
        capacity,
        pending,
        span,
    }))
}

/// `state name: type [= literal];` (docs/language.md, "State and conditions").
pub(super) fn state(
    input: ParseStream,
    attrs: Vec<syn::Attribute>,
    persistent: bool,
    keyword_span: Span,
    cx: &mut Cx,
) -> syn::Result<Item> {
    not_persistent(
        cx,
        persistent,
        keyword_span,
        "a state variable",
        "remove `persistent`: a state variable lives as long as the run",
    );
    let name: Ident = input.parse()?;
    input.parse::<Token![:]>()?;
    let ty_name = input.call(Ident::parse_any)?;
    if state_type(&ty_name.to_string()).is_none() {
        let hint = match ty_name.to_string().as_str() {
            "i64" | "i32" | "u32" | "u64" | "usize" | "isize" => "write `int`",
            "f64" | "f32" => "write `float`",
            "String" | "str" => "write `string`",
            _ => "a state variable is a `bool`, an `int`, a `float` or a `string`",
        };
        cx.diags.push(
            Diagnostic::error(
                ty_name.span(),
                format!("`{ty_name}` is not a type of state variable"),
            )
            .with_hint(hint),
        );
    }
    let init = if input.peek(Token![=]) {
        input.parse::<Token![=]>()?;
        cx.hint = Some(STATE_HINT);
        Some(cond::parse_lit(input)?)
    } else {
        None
    };
    if !input.peek(Token![;]) {
        cx.hint = Some(STATE_HINT);
        return Err(input.error("expected `;` or `= value` after the state variable's type"));
    }
    input.parse::<Token![;]>()?;
    let span = name.span();
    Ok(Item::State(StateDecl {
        attrs,
        name,
        ty_name,
        init,
        span,
    }))
}

/// `environment { entry* }`, each entry `VAR: v1, v2 [at most N] [when COND];` or `external
/// "name" [at most N] [when COND];` (docs/verification.md, "The environment").
pub(super) fn environment(
    input: ParseStream,
    keyword_span: Span,
    cx: &mut Cx,
) -> syn::Result<Item> {
    let content;
    syn::braced!(content in input);
    let mut entries = Vec::new();
    while !content.is_empty() {
        cx.hint = Some(ENV_HINT);
        let span = content.span();
        let target = if content.peek(syn::Ident) && content.peek2(syn::LitStr) {
            let word = content.call(Ident::parse_any)?;
            if word != "external" {
                return Err(syn::Error::new(
                    word.span(),
                    format!("expected `external \"name\"` or a state variable, found `{word}`"),
                ));
            }
            EnvTarget::External(content.parse()?)
        } else {
            let name: Ident = content.parse()?;
            content.parse::<Token![:]>()?;
            EnvTarget::State(name)
        };
        let mut values = Vec::new();
        if matches!(target, EnvTarget::State(_)) {
            values.push(cond::parse_lit(&content)?);
            while content.peek(Token![,]) {
                content.parse::<Token![,]>()?;
                values.push(cond::parse_lit(&content)?);
            }
        }
        let mut at_most = None;
        let mut when = None;
        loop {
            if content.peek(syn::Ident)
                && content
                    .fork()
                    .call(Ident::parse_any)
                    .is_ok_and(|w| w == "at")
            {
                content.call(Ident::parse_any)?;
                let most = content.call(Ident::parse_any)?;
                if most != "most" {
                    return Err(syn::Error::new(most.span(), "expected `at most N`"));
                }
                let n: syn::LitInt = content.parse()?;
                at_most = Some((n.base10_parse::<u32>()?, n.span()));
            } else if content.peek(syn::Ident)
                && content
                    .fork()
                    .call(Ident::parse_any)
                    .is_ok_and(|w| w == "when")
            {
                content.call(Ident::parse_any)?;
                when = Some(cond::parse_cond(&content)?);
            } else {
                break;
            }
        }
        content.parse::<Token![;]>()?;
        entries.push(EnvEntry {
            target,
            values,
            at_most,
            when,
            span,
        });
    }
    cx.hint = None;
    Ok(Item::Environment(EnvironmentDecl {
        entries,
        span: keyword_span,
    }))
}

const ENV_HINT: &str = "an environment entry reads `var: value, value [at most N] [when condition];` \
     or `external \"name\" [at most N] [when condition];`";

const STATE_HINT: &str = "a state variable reads `state name: type [= value];`, its type \
     `bool`, `int`, `float` or `string`, its value a literal or `unknown` (the default)";
