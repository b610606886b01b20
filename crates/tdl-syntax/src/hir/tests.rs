//! Unit tests of the resolution pass: what names denote, what gets a local, and the sites and
//! indexes both consumers read.

use super::{BodyScope, Def, FileScope, IndexError, Named, Resolution, Tdl};
use crate::ast::{Item, Tag, TagIndex, TagKind, Task};
use crate::parse_str;

/// The tasks of `src` (resolution runs on trees with errors too).
fn tasks(src: &str) -> Vec<Task> {
    parse_str("t.tdl", src)
        .file
        .items
        .into_iter()
        .filter_map(|it| match it {
            Item::Task(task) => Some(task),
            _ => None,
        })
        .collect()
}

/// The named tags of a body's constraints, in source order.
fn tags(scope: &BodyScope<'_>) -> Vec<Tag> {
    scope.refs.iter().map(|it| it.tag.clone()).collect()
}

/// The iteration indexes of a named tag.
fn indexes(tag: &Tag) -> Vec<TagIndex> {
    match &tag.kind {
        TagKind::Named { indexes, .. } => indexes.clone(),
        _ => Vec::new(),
    }
}

fn spawn_of(named: Option<Named<'_>>) -> Option<usize> {
    match named {
        Some(Named {
            def: Def::Spawn(id),
            ..
        }) => Some(id),
        _ => None,
    }
}

#[test]
fn labels_win_over_task_names_and_a_task_spawned_twice_is_ambiguous() {
    let tasks = tasks(
        "goal g() {
             a: spawn b();
             spawn b();
             spawn a();
             spawn c() with serial a, serial b;
             g1: with (parallel) { spawn d(); }
             spawn e() with serial g1;
         }",
    );
    let scope = BodyScope::new(&tasks[0]);
    let tags = tags(&scope);
    // `a` is the label of the first spawn, not the task `a` spawned third.
    assert_eq!(spawn_of(scope.named(&tags[0])), Some(0));
    assert!(matches!(scope.resolve(&tags[1]), Resolution::Ambiguous(ids) if ids == [0, 1]));
    assert!(matches!(
        scope.named(&tags[2]),
        Some(Named {
            def: Def::Group(0),
            ..
        })
    ));
}

#[test]
fn the_first_of_duplicate_labels_wins() {
    let tasks = tasks(
        "goal g() {
             x: spawn a();
             x: with (parallel) { spawn b(); }
             y: spawn c() with on terminate x: spawn z();
             spawn d() with serial x;
         }",
    );
    let scope = BodyScope::new(&tasks[0]);
    let dups: Vec<String> = scope
        .duplicate_labels
        .iter()
        .map(|it| it.0.to_string())
        .collect();
    assert_eq!(dups, ["x", "x"]);
    assert_eq!(spawn_of(scope.named(&tags(&scope)[0])), Some(0));
}

#[test]
fn only_named_spawns_and_groups_get_locals_and_their_loops_count() {
    let tasks = tasks(
        "goal g(n: u32) {
             spawn a();
             t: spawn a();
             for i in 0..n { while go() { mv: spawn m(i); } }
             for j in 0..n { spawn quiet(); }
             grp: with (parallel) { spawn b(); }
             spawn c() with serial t, serial mv[0][1], serial grp;
             spawn r#type() with on terminate spawn z();
             r#type wait;
         }",
    );
    let scope = BodyScope::new(&tasks[0]);
    let vars: Vec<Option<String>> = scope
        .spawns
        .iter()
        .map(|it| it.var.as_ref().map(ToString::to_string))
        .collect();
    assert_eq!(
        vars,
        [
            None,
            Some("tdl_t".to_owned()),
            Some("tdl_mv".to_owned()),
            None,
            None,
            None,
            Some("tdl_type".to_owned()),
        ]
    );
    assert_eq!(
        scope.groups[0].var.as_ref().map(ToString::to_string),
        Some("tdl_grp".to_owned())
    );
    assert_eq!(scope.spawns[2].site.loops, [0, 1]);
    assert!(scope.is_counted(0) && scope.is_counted(1) && !scope.is_counted(2));
    assert!(!scope.uses_previous);
}

#[test]
fn sites_number_every_statement_in_source_order() {
    let tasks = tasks(
        "goal g() {
             f1 wait;
             let x = 1;
             f1: spawn fetch(x);
             if x > 0 { spawn other() with sequential execution previous; }
         }",
    );
    let scope = BodyScope::new(&tasks[0]);
    let Tdl::Constrain(_, site) = &scope.stmts[0] else {
        panic!("expected the constraint statement first")
    };
    let named = scope.named(&tags(&scope)[0]);
    let def = named.map(|it| it.def).expect("f1 resolves");
    assert_eq!((site.position, scope.site(def).position), (1, 3));
    assert_eq!(
        scope.stmts.len(),
        3,
        "Rust statements are not TDL statements"
    );
    assert!(scope.uses_previous);
}

#[test]
fn current_index_needs_the_loop_around_the_use() {
    let tasks = tasks(
        "goal g() {
             for i in 0..3 { m: spawn a(i); spawn b() with serial m[.]; }
             spawn c() with serial m[.];
             spawn d() with serial m[0][1];
         }",
    );
    let scope = BodyScope::new(&tasks[0]);
    let tags = tags(&scope);
    let current = indexes(&tags[0]);
    assert!(scope.indexes(0, &current, &[0]).is_ok());
    assert_eq!(
        scope.indexes(0, &current, &[]).err(),
        Some(IndexError::CurrentOutside)
    );
    assert_eq!(
        scope.indexes(0, &indexes(&tags[2]), &[]).err(),
        Some(IndexError::TooMany)
    );
    // A spawn outside loops takes no index; too many is the index count's report.
    assert!(
        scope
            .indexes(2, &current, &[])
            .is_ok_and(|it| it.is_empty())
    );
}

#[test]
fn exception_ancestry_follows_declared_parents_and_cuts_cycles() {
    let parse = parse_str(
        "t.tdl",
        "exception A : Outside; exception B : A; exception C : B;
         exception X : Y; exception Y : X; exception A;",
    );
    let file = FileScope::new(&parse.file);
    assert_eq!(file.ancestry("C"), ["B", "A", "Outside"]);
    assert_eq!(file.ancestry("X"), ["Y"]);
    assert_eq!(file.duplicates.len(), 1);
    assert!(file.declares_exception("Y") && !file.declares_exception("Outside"));
    let names: Vec<&str> = file.exception_names().collect();
    assert_eq!(names, ["A", "B", "C", "X", "Y"]);
}

/// What a visitor met: each spawn's task, and each set of branches with whether one surely runs.
#[derive(Default)]
struct Met {
    seen: Vec<String>,
}

impl<'a> super::Visit<'a> for Met {
    fn stmt(&mut self, stmt: &'a crate::ast::Stmt) {
        if let crate::ast::Stmt::Spawn(spawn) = stmt {
            self.seen.push(spawn.task.to_string());
        }
        super::walk_stmt(self, stmt);
    }

    fn branches(&mut self, branches: Vec<super::Branch<'a>>, exhaustive: bool) {
        self.seen.push(format!(
            "{} branches, exhaustive {exhaustive}",
            branches.len()
        ));
        for branch in branches {
            self.branch(branch);
        }
    }

    fn code(&mut self, code: proc_macro2::TokenStream) {
        self.seen.push(format!("code {code}"));
    }
}

#[test]
fn the_visitor_meets_every_statement_in_source_order() {
    let tasks = tasks(
        "goal g(n: u32) {
            spawn a();
            if n > 1 { spawn b(); } else if n > 0 { spawn c(); }
            match n { 0 => { spawn d(); } m if m > 5 => { spawn e(); } _ => {} }
            for i in 0..n { with (serial) { spawn f(); } }
            loop { { spawn h(); } break; }
        }",
    );
    let mut met = Met::default();
    super::Visit::block(&mut met, &tasks[0].body);
    assert_eq!(
        met.seen,
        [
            "a",
            "2 branches, exhaustive false",
            "code n > 1",
            "b",
            "code n > 0",
            "c",
            "code n",
            "3 branches, exhaustive true",
            "code ",
            "d",
            "code m > 5",
            "e",
            "code ",
            "code 0 .. n",
            "f",
            "h",
        ]
    );
}
