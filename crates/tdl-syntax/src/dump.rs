//! A compact, indented text dump of the syntax tree, one node per line.
//!
//! Used by the parser snapshot tests (`tests/it/data.rs`) and handy when debugging the parser:
//! constraints, tags and times print in the one canonical TDL spelling of `print.rs` (joined
//! keywords and synonyms resolved), the Rust fragments of statements as their token text.

use std::fmt::Write as _;

use quote::ToTokens;

use crate::ast::{Ast, Block, Constraint, Else, If, Item, Match, Spawn, Stmt, Task};
use crate::print;

/// Dumps the tree as indented text.
pub fn dump(ast: &Ast) -> String {
    let mut out = String::new();
    for item in &ast.items {
        match item {
            Item::Task(task) => dump_task(&mut out, task),
            Item::Exception(exc) => {
                let parent = exc
                    .parent
                    .as_ref()
                    .map(|it| format!(" : {it}"))
                    .unwrap_or_default();
                let fields: Vec<String> = exc
                    .fields
                    .iter()
                    .map(|it| format!("{}: {}", it.name, tokens(&it.ty)))
                    .collect();
                let _ = writeln!(
                    out,
                    "exception {}{parent} {{{}}}",
                    exc.name,
                    fields.join(", ")
                );
            }
            Item::Resource(r) => {
                let pending = r
                    .pending
                    .as_ref()
                    .map(|it| format!(" pending {it}"))
                    .unwrap_or_default();
                let _ = writeln!(out, "resource {}({}){pending}", r.name, r.capacity);
            }
            Item::State(it) => {
                let init = it
                    .init
                    .as_ref()
                    .map(|it| format!(" = {}", it.value))
                    .unwrap_or_default();
                let _ = writeln!(out, "state {}: {}{init}", it.name, it.ty_name);
            }
            Item::Environment(env) => {
                let _ = writeln!(out, "environment");
                for e in &env.entries {
                    let _ = writeln!(out, "  {}", crate::print::env_entry(e));
                }
            }
            Item::Extern(e) => {
                let args: Vec<String> = e
                    .args
                    .iter()
                    .map(|it| format!("{}: {}", it.name, tokens(&it.ty)))
                    .collect();
                let result = e
                    .result
                    .as_ref()
                    .map(|it| format!(" -> {}", tokens(it)))
                    .unwrap_or_default();
                let _ = writeln!(
                    out,
                    "extern {} {}({}){result}",
                    e.kind.as_str(),
                    e.name,
                    args.join(", ")
                );
            }
            Item::Rust(item) => {
                let _ = writeln!(out, "rust item: {}", tokens(item.as_ref()));
            }
        }
    }
    for allow in &ast.allows {
        let (from, to) = (allow.from.start(), allow.to.end());
        let _ = writeln!(
            out,
            "allow tdl::{} over {}:{}..{}:{}",
            allow.lint.name(),
            from.line,
            from.column + 1,
            to.line,
            to.column + 1
        );
    }
    out
}

fn tokens(it: &impl ToTokens) -> String {
    it.to_token_stream().to_string()
}

fn exprs(args: &[syn::Expr]) -> String {
    args.iter().map(tokens).collect::<Vec<_>>().join(", ")
}

fn dump_task(out: &mut String, task: &Task) {
    let args: Vec<String> = task
        .args
        .iter()
        .map(|it| {
            let mutable = if it.mutable { "mut " } else { "" };
            format!("{mutable}{}: {}", it.name, tokens(&it.ty))
        })
        .collect();
    let persistent = if task.persistent { "persistent " } else { "" };
    let blocking = if task.blocking.is_some() {
        "blocking "
    } else {
        ""
    };
    let idempotent = if task.idempotent { "idempotent " } else { "" };
    let vis = match task.vis {
        syn::Visibility::Inherited => String::new(),
        ref vis => format!("{} ", tokens(vis)),
    };
    let result = task
        .result
        .as_ref()
        .map(|it| format!(" -> {}", tokens(it)))
        .unwrap_or_default();
    let handles = task
        .handles
        .as_ref()
        .map(|it| match &task.caught {
            Some(name) => format!(" handles {it} as {name}"),
            None => format!(" handles {it}"),
        })
        .unwrap_or_default();
    let for_task = task
        .for_task
        .as_ref()
        .map(|it| format!(" for {it}"))
        .unwrap_or_default();
    let tap = task
        .tap
        .as_ref()
        .map(|t| format!(" {} {}", if t.after { "after" } else { "before" }, t.target))
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "{vis}{persistent}{blocking}{idempotent}{} {}({}){result}{handles}{for_task}{tap}",
        if task.tap.is_some() {
            "wiretap"
        } else {
            task.kind.as_str()
        },
        task.name,
        args.join(", ")
    );
    for constraint in &task.constraints {
        let mut text = String::new();
        print::task_constraint(&constraint.kind, &mut text);
        let _ = writeln!(out, "  | {text}");
    }
    dump_block(out, &task.body, 1);
}

fn line(out: &mut String, depth: usize, text: &str) {
    let _ = writeln!(out, "{:width$}{text}", "", width = depth * 2);
}

fn labels(labels: &[proc_macro2::Ident]) -> String {
    labels.iter().map(|it| format!("{it}: ")).collect()
}

fn dump_block(out: &mut String, block: &Block, depth: usize) {
    for stmt in &block.stmts {
        dump_stmt(out, stmt, depth);
    }
}

fn dump_constraints(out: &mut String, constraints: &[Constraint], depth: usize) {
    for it in constraints {
        line(out, depth, &format!("| {}", constraint(it)));
    }
}

fn dump_stmt(out: &mut String, stmt: &Stmt, depth: usize) {
    match stmt {
        Stmt::Rust(it) => line(out, depth, &format!("rust: {}", it.tokens)),
        Stmt::Spawn(it) => dump_spawn(out, it, depth),
        Stmt::With(it) => {
            let list: Vec<String> = it.constraints.iter().map(constraint).collect();
            line(
                out,
                depth,
                &format!("{}with ({})", labels(&it.labels), list.join(", ")),
            );
            dump_block(out, &it.body, depth + 1);
        }
        Stmt::Constrain(it) => {
            line(
                out,
                depth,
                &format!(
                    "constrain {} {}",
                    print::tag(&it.tag),
                    constraint(&it.constraint)
                ),
            );
        }
        Stmt::Bind(it) => line(
            out,
            depth,
            &format!("bind {} = {}", it.name, tokens(&it.expr)),
        ),
        Stmt::Succeed(_) => line(out, depth, "succeed"),
        Stmt::Fail(it) => {
            let exc = it
                .exception
                .as_ref()
                .map(|it| format!(" {it}"))
                .unwrap_or_default();
            let fields: Vec<String> = it.fields.iter().map(tokens).collect();
            let fields = if fields.is_empty() {
                String::new()
            } else {
                format!(" {{ {} }}", fields.join(", "))
            };
            line(out, depth, &format!("fail{exc}{fields}"));
        }
        Stmt::Resource(it) => line(out, depth, &format!("{} {}", it.op.as_str(), it.name)),
        Stmt::Set(it) => line(
            out,
            depth,
            &format!("set {} = {}", it.name, tokens(&it.value)),
        ),
        Stmt::Raise(it) => line(out, depth, &format!("raise {}", print::external(&it.name))),
        Stmt::Log(it) => line(out, depth, &format!("log {}", it.format_args())),
        Stmt::Bypass(_) => line(out, depth, "bypass"),
        Stmt::Trigger(_) => line(out, depth, "trigger"),
        Stmt::Retry(it) => match &it.args {
            None => line(out, depth, "retry"),
            Some(args) => {
                let args: Vec<String> = args
                    .iter()
                    .map(|a| a.to_token_stream().to_string())
                    .collect();
                line(out, depth, &format!("retry with ({})", args.join(", ")))
            }
        },
        Stmt::If(it) => dump_if(out, it, depth, "if"),
        Stmt::For(it) => {
            let label = it
                .label
                .as_ref()
                .map(|it| format!("{it}: "))
                .unwrap_or_default();
            line(
                out,
                depth,
                &format!("{label}for {} in {}", tokens(&it.pat), tokens(&it.expr)),
            );
            dump_block(out, &it.body, depth + 1);
        }
        Stmt::While(it) => {
            let label = it
                .label
                .as_ref()
                .map(|it| format!("{it}: "))
                .unwrap_or_default();
            line(out, depth, &format!("{label}while {}", tokens(&it.cond)));
            dump_block(out, &it.body, depth + 1);
        }
        Stmt::Loop(it) => {
            let label = it
                .label
                .as_ref()
                .map(|it| format!("{it}: "))
                .unwrap_or_default();
            line(out, depth, &format!("{label}loop"));
            dump_block(out, &it.body, depth + 1);
        }
        Stmt::Match(it) => dump_match(out, it, depth),
        Stmt::Block(it) => {
            line(out, depth, "block");
            dump_block(out, it, depth + 1);
        }
    }
}

fn dump_spawn(out: &mut String, it: &Spawn, depth: usize) {
    let binding = match &it.binding {
        Some(binding) => {
            let ty = binding
                .ty
                .as_ref()
                .map(|it| format!(": {}", tokens(it)))
                .unwrap_or_default();
            match &binding.target {
                crate::ast::BindTarget::Let(pat) => format!("let {}{ty} = ", tokens(pat)),
                crate::ast::BindTarget::Assign(place) => format!("{} = ", tokens(place)),
            }
        }
        None => String::new(),
    };
    let text = format!(
        "{}{binding}spawn {}({})",
        labels(&it.labels),
        it.task,
        exprs(&it.args)
    );
    line(out, depth, &text);
    dump_constraints(out, &it.constraints, depth + 1);
}

fn dump_match(out: &mut String, it: &Match, depth: usize) {
    line(out, depth, &format!("match {}", tokens(&it.expr)));
    for arm in &it.arms {
        let guard = arm
            .guard
            .as_ref()
            .map(|it| format!(" if {}", tokens(it)))
            .unwrap_or_default();
        line(
            out,
            depth + 1,
            &format!("arm {}{guard} =>", tokens(&arm.pat)),
        );
        dump_block(out, &arm.body, depth + 2);
    }
}

fn dump_if(out: &mut String, it: &If, depth: usize, keyword: &str) {
    line(out, depth, &format!("{keyword} {}", tokens(&it.cond)));
    dump_block(out, &it.then_branch, depth + 1);
    match it.else_branch.as_deref() {
        Some(Else::If(next)) => dump_if(out, next, depth, "else if"),
        Some(Else::Block(block)) => {
            line(out, depth, "else");
            dump_block(out, block, depth + 1);
        }
        None => {}
    }
}

/// A constraint in canonical TDL spelling (`print.rs`).
fn constraint(it: &Constraint) -> String {
    let mut out = String::new();
    print::constraint(&it.kind, &mut out);
    out
}
