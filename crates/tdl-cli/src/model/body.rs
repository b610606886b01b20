//! What one task body does, read from its resolved body (`tdl_syntax::hir`): its spawn sites,
//! the constraints on each with `previous` where they apply, the relations between sites, and the
//! text of each constraint with its tags linked to the sites they name.

use std::collections::BTreeSet;

use tdl_syntax::hir::{self, BodyScope, Def, Resolution, Tdl};
use tdl_syntax::{
    Constraint, ConstraintKind, Tag, TagIndex, TagKind, TaskConstraintKind, Then, When, print,
};

use super::{
    Endpoint, Origin, Piece, Relation, RelationKind, Site, TaskInfo, Text, handler_use, plain,
};

/// Fills in the sites, relations, handlers and notes of a task from its resolved body.
pub(super) fn analyse(info: &mut TaskInfo<'_>, body: &BodyScope<'_>) {
    let task = info.task;
    let (mut sites, spawn_sites, cleanup_sites) = body_sites(body);
    let mut notes = Vec::new();
    for c in &task.constraints {
        match &c.kind {
            TaskConstraintKind::ExceptionHandler(h) => info.handlers.push(handler_use(h)),
            TaskConstraintKind::OnTerminate(ot) => {
                sites.push(Site::new(
                    ot.task.to_string(),
                    print::exprs(&ot.args),
                    Vec::new(),
                    Origin::OnTerminate(None),
                    ot.task.span().start().line,
                ));
            }
            kind => {
                let mut text = String::new();
                print::task_constraint(kind, &mut text);
                notes.push(vec![Piece::Text(text)]);
            }
        }
    }
    let all_sites = sites.clone();
    info.tags = Vec::new();
    let scope = Scope {
        body,
        spawn_sites: &spawn_sites,
        cleanup_sites: &cleanup_sites,
        sites: &all_sites,
    };
    let mut relations = BTreeSet::new();
    let pending = pending(&scope);
    info.tags = resolved_tags(&scope, &pending, info.file_index);
    for p in pending {
        let targets: Vec<usize> = match p.target {
            Target::Site(i) => vec![i],
            Target::Tag(tag) => match scope.resolve(tag, &p.prev) {
                Resolved::Sites(sites) => sites,
                Resolved::Task | Resolved::Own | Resolved::Bound(_) | Resolved::Unknown => {
                    // A constraint on the task itself, or on a node the body holds in Rust.
                    let mut text = scope.tag_text(tag, &p.prev);
                    text.push(Piece::Text(" ".into()));
                    text.extend(constraint_text(&p.constraint.kind, &scope, &p.prev));
                    notes.push(text);
                    continue;
                }
            },
        };
        for t in targets {
            apply(&mut sites, &mut relations, &scope, t, &p);
        }
    }
    waits(&scope, &mut relations);
    info.sites = sites;
    info.relations = relations.into_iter().collect();
    info.notes = notes;
    info.raises = body.raises();
    info.retries = body.stmts.iter().any(|it| matches!(it, Tdl::Retry(_)));
    info.bypasses = body.stmts.iter().any(|it| matches!(it, Tdl::Bypass(_)));
    info.triggers = body.stmts.iter().any(|it| matches!(it, Tdl::Trigger(_)));
    for set in &body.sets {
        let name = set.name.to_string();
        if !info.sets.contains(&name) {
            info.sets.push(name);
        }
    }
    for raise in &body.raises_external {
        let name = print::external(&raise.name);
        if !info.raises_external.contains(&name) {
            info.raises_external.push(name);
        }
    }
}

/// The order a body's waits make: a body waits for a waited spawn (`with wait`, `with outcome`, a
/// value taken, or a spawn of a `with (wait)` group) to end before it goes on, so each spawn that
/// may come just after it (`previous`) starts after its end, unless a constraint orders the two
/// already. Drawn in body order, a sequence of waited spawns is a sequence, not a fan-out.
fn waits(scope: &Scope<'_, '_>, relations: &mut BTreeSet<Relation>) {
    let body = scope.body;
    let waited = |id: usize| {
        let def = &body.spawns[id];
        let on_spawn = def.spawn.binding.is_some()
            || def
                .spawn
                .constraints
                .iter()
                .any(|c| matches!(c.kind, ConstraintKind::Wait | ConstraintKind::Outcome));
        let in_group = def.groups.iter().any(|&g| {
            body.groups[g]
                .group
                .constraints
                .iter()
                .any(|c| matches!(c.kind, ConstraintKind::Wait))
        });
        on_spawn || in_group
    };
    for (to, def) in body.spawns.iter().enumerate() {
        let Some(previous) = body.previous_at(def.site.position) else {
            continue;
        };
        for &from in previous.may.iter().filter(|it| waited(**it)) {
            let (from, to) = (
                Endpoint::Site(scope.spawn_sites[from]),
                scope.spawn_sites[to],
            );
            // A constraint that orders them already says it.
            let ordered = relations
                .iter()
                .any(|r| r.from == from && r.to == to && r.kind == RelationKind::Order);
            if !ordered {
                relations.insert(Relation {
                    from,
                    to,
                    kind: RelationKind::Order,
                    label: "after its end".into(),
                });
            }
        }
    }
}

/// Every tag of the pending constraints, `previous` aside, as [`Scope::resolve`] resolves it.
fn resolved_tags(
    scope: &Scope<'_, '_>,
    pending: &[Pending<'_>],
    file: usize,
) -> Vec<hir::ResolvedTag> {
    let mut out = Vec::new();
    for p in pending {
        let mut tags: Vec<&Tag> = Vec::new();
        if let Target::Tag(tag) = p.target {
            tags.push(tag);
        }
        match &p.constraint.kind {
            ConstraintKind::Sequential { tag: Some(tag), .. }
            | ConstraintKind::Serial { tag: Some(tag) } => {
                tags.push(tag);
            }
            ConstraintKind::Trigger { when, .. } => tags.extend(when.event().map(|it| &it.tag)),
            _ => {}
        }
        for tag in tags {
            let targets = match (&tag.kind, scope.resolve(tag, &p.prev)) {
                (TagKind::Previous, _) => continue,
                (_, Resolved::Sites(sites)) => {
                    sites.iter().filter_map(|&s| scope.target(s)).collect()
                }
                (_, Resolved::Task) => vec![hir::TagTarget::Parent],
                (_, Resolved::Own) => vec![hir::TagTarget::This],
                (_, Resolved::Bound(name)) => vec![hir::TagTarget::Bound(name)],
                (_, Resolved::Unknown) => Vec::new(),
            };
            out.push(hir::ResolvedTag::new(file, tag, targets));
        }
    }
    out
}

/// The spawn sites of a body: each spawn followed by its on-terminate tasks, in source order;
/// with the site of each spawn and of each labelled on-terminate task.
fn body_sites(body: &BodyScope<'_>) -> (Vec<Site>, Vec<usize>, Vec<usize>) {
    // Sites are numbered as the body's spawns and their on-terminate tasks come.
    let mut sites = Vec::new();
    let mut spawn_sites = Vec::with_capacity(body.spawns.len());
    let mut cleanup_sites = vec![0; body.cleanups.len()];
    for def in &body.spawns {
        let spawn = def.spawn;
        let i = sites.len();
        spawn_sites.push(i);
        let labels: Vec<String> = spawn.labels.iter().map(ToString::to_string).collect();
        let mut own = vec![Site::new(
            spawn.task.to_string(),
            print::exprs(&spawn.args),
            labels,
            Origin::Body,
            spawn.task.span().start().line,
        )];
        for c in &spawn.constraints {
            if let ConstraintKind::OnTerminate(ot) = &c.kind {
                if let Some(id) = body.cleanup_id(ot) {
                    cleanup_sites[id] = i + own.len();
                }
                let labels: Vec<String> = ot.labels.iter().map(ToString::to_string).collect();
                own.push(Site::new(
                    ot.task.to_string(),
                    print::exprs(&ot.args),
                    labels,
                    Origin::OnTerminate(Some(i)),
                    ot.task.span().start().line,
                ));
            }
        }
        for site in &mut own {
            site.repeated = !def.site.loops.is_empty();
            site.conditional = def.site.branch;
        }
        sites.extend(own);
    }
    (sites, spawn_sites, cleanup_sites)
}

/// Every constraint of a body, in source order, with what it applies to and `previous` there:
/// a spawn's own, then those of its `with` groups, outermost first (for the innermost group,
/// `previous` is the entity before the spawn; for an outer one, the entity before the group nested
/// in it); and the constraint statements.
fn pending<'a>(scope: &Scope<'_, 'a>) -> Vec<Pending<'a>> {
    let body = scope.body;
    let mut out = Vec::new();
    for stmt in &body.stmts {
        match stmt {
            Tdl::Spawn(id) => {
                let def = &body.spawns[*id];
                let site = scope.spawn_sites[*id];
                let prev = scope.previous(def.site.position);
                for c in &def.spawn.constraints {
                    if !matches!(c.kind, ConstraintKind::OnTerminate(_)) {
                        out.push(Pending {
                            target: Target::Site(site),
                            constraint: c,
                            prev: prev.clone(),
                        });
                    }
                }
                for (k, &group) in def.groups.iter().enumerate() {
                    let prev = match def.groups.get(k + 1) {
                        Some(&inner) => scope.previous(body.groups[inner].site.position),
                        None => prev.clone(),
                    };
                    for c in &body.groups[group].group.constraints {
                        out.push(Pending {
                            target: Target::Site(site),
                            constraint: c,
                            prev: prev.clone(),
                        });
                    }
                }
            }
            Tdl::Constrain(it, site) => out.push(Pending {
                target: Target::Tag(&it.tag),
                constraint: &it.constraint,
                prev: scope.previous(site.position),
            }),
            Tdl::With(_) | Tdl::Fail(_) | Tdl::Bypass(_) | Tdl::Trigger(_) | Tdl::Retry(_) => {}
        }
    }
    out
}

/// Applies one pending constraint to the spawn site `t`.
fn apply(
    sites: &mut [Site],
    relations: &mut BTreeSet<Relation>,
    scope: &Scope<'_, '_>,
    t: usize,
    p: &Pending<'_>,
) {
    let kind = &p.constraint.kind;
    let text = constraint_text(kind, scope, &p.prev);
    let mut relate = |tag: Option<&Tag>, kind: RelationKind, label: String| -> bool {
        let from: Vec<Endpoint> = match tag.map(|tag| scope.resolve(tag, &p.prev)) {
            None => p.prev.iter().map(|&s| Endpoint::Site(s)).collect(),
            Some(Resolved::Sites(s)) => s.into_iter().map(Endpoint::Site).collect(),
            Some(Resolved::Task) => vec![Endpoint::Task],
            Some(Resolved::Own | Resolved::Bound(_) | Resolved::Unknown) => Vec::new(),
        };
        for from in &from {
            relations.insert(Relation {
                from: *from,
                to: t,
                kind,
                label: label.clone(),
            });
        }
        !from.is_empty()
    };
    let site = &mut sites[t];
    let mut flag = |f: &'static str| {
        if !site.flags.contains(&f) {
            site.flags.push(f);
        }
    };
    match kind {
        ConstraintKind::Wait => flag("wait"),
        ConstraintKind::Outcome => flag("outcome"),
        ConstraintKind::Propagate => flag("propagate"),
        ConstraintKind::Uses(_) => flag("uses resources"),
        ConstraintKind::Priority(_) => flag("priority"),
        ConstraintKind::DenyIfBusy => flag("deny if busy"),
        ConstraintKind::Parallel => {}
        ConstraintKind::ExceptionHandler(h) => site.handlers.push(handler_use(h)),
        ConstraintKind::Sequential { facet, tag } => {
            relate(
                tag.as_ref(),
                RelationKind::Order,
                format!("sequential {}", facet.as_str()),
            );
        }
        ConstraintKind::Serial { tag } => {
            relate(tag.as_ref(), RelationKind::Order, "serial".into());
        }
        ConstraintKind::Trigger { when, then } => {
            let related = when.event().is_some_and(|ev| {
                let kind = match then {
                    Then::Enable(_) => RelationKind::Order,
                    Then::Terminate => RelationKind::Terminate,
                    Then::Activate => RelationKind::Activate,
                    // On a condition, never on an event: a note of the site below.
                    Then::Skip | Then::Invariant | Then::Pause => RelationKind::Order,
                };
                relate(Some(&ev.tag), kind, when_label(when, *then))
            });
            if !related {
                site.notes.push(plain(&text));
            }
        }
        _ => site.notes.push(plain(&text)),
    }
    site.constraints.push(text);
}

/// What a constraint applies to.
#[derive(Clone)]
enum Target<'a> {
    /// The spawn site (a constraint written on the spawn or its group).
    Site(usize),
    /// A constraint statement's tag.
    Tag(&'a Tag),
}

/// A constraint to apply.
#[derive(Clone)]
struct Pending<'a> {
    target: Target<'a>,
    constraint: &'a Constraint,
    /// The sites `previous` may be where the constraint applies.
    prev: Vec<usize>,
}

/// What a tag names.
enum Resolved {
    /// Spawn sites of the body.
    Sites(Vec<usize>),
    /// The task itself (`parent`, `this`).
    Task,
    /// The node being spawned (`self`, `child`).
    Own,
    /// A node bound in Rust (`bind name = …;`).
    Bound(String),
    /// Nothing known.
    Unknown,
}

/// The names of one body, resolved by the front end, and its spawn sites.
struct Scope<'s, 'a> {
    body: &'s BodyScope<'a>,
    /// The site of each spawn.
    spawn_sites: &'s [usize],
    /// The site of each labelled on-terminate task.
    cleanup_sites: &'s [usize],
    sites: &'s [Site],
}

impl Scope<'_, '_> {
    /// What site `s` is: a spawn, or an on-terminate task of one.
    fn target(&self, s: usize) -> Option<hir::TagTarget> {
        match self.sites.get(s)?.origin {
            Origin::Body => self
                .spawn_sites
                .iter()
                .position(|it| *it == s)
                .map(hir::TagTarget::Spawn),
            Origin::OnTerminate(Some(of)) => {
                let spawn = self.spawn_sites.iter().position(|it| *it == of)?;
                Some(hir::TagTarget::OnTerminate(spawn, s - of - 1))
            }
            Origin::OnTerminate(None) => None,
        }
    }

    /// The sites `previous` may be at the statement at `position`.
    fn previous(&self, position: usize) -> Vec<usize> {
        self.body
            .previous_at(position)
            .map(|it| it.may.iter().map(|&id| self.spawn_sites[id]).collect())
            .unwrap_or_default()
    }

    fn resolve(&self, tag: &Tag, prev: &[usize]) -> Resolved {
        match &tag.kind {
            TagKind::Named { .. } => match self.body.resolve(tag) {
                Resolution::Named(named) => match named.def {
                    Def::Spawn(id) => Resolved::Sites(vec![self.spawn_sites[id]]),
                    Def::Group(id) => Resolved::Sites(
                        self.body
                            .members(id)
                            .into_iter()
                            .map(|it| self.spawn_sites[it])
                            .collect(),
                    ),
                    Def::OnTerminate(id) => Resolved::Sites(vec![self.cleanup_sites[id]]),
                    Def::Bound(bind) => Resolved::Bound(bind.name.to_string()),
                },
                Resolution::Ambiguous(ids) => {
                    Resolved::Sites(ids.into_iter().map(|it| self.spawn_sites[it]).collect())
                }
                Resolution::Unknown
                | Resolution::Previous
                | Resolution::This
                | Resolution::Parent => Resolved::Unknown,
            },
            TagKind::Previous if prev.is_empty() => Resolved::Unknown,
            TagKind::Previous => Resolved::Sites(prev.to_vec()),
            TagKind::Child => Resolved::Own,
            TagKind::Parent => Resolved::Task,
        }
    }
    /// The tag as written, a reference to the spawn it names; `previous` followed by the spawns
    /// it may be.
    fn tag_text(&self, tag: &Tag, prev: &[usize]) -> Text {
        match &tag.kind {
            TagKind::Named { name, indexes } => {
                let mut written = name.to_string();
                for index in indexes {
                    match index {
                        TagIndex::Expr(e) => written.push_str(&format!("[{}]", print::expr(e))),
                        TagIndex::Current => written.push_str("[.]"),
                    }
                }
                match self.resolve(tag, prev) {
                    Resolved::Sites(sites) if !sites.is_empty() => {
                        vec![Piece::Site(sites[0], written)]
                    }
                    _ => vec![Piece::Text(written)],
                }
            }
            TagKind::Previous => self.previous_text(prev),
            TagKind::Child => vec![Piece::Text("self".into())],
            TagKind::Parent => vec![Piece::Text("parent".into())],
        }
    }

    /// `previous`, followed by the spawns it may be.
    fn previous_text(&self, prev: &[usize]) -> Text {
        let mut text = vec![Piece::Text("previous".into())];
        if !prev.is_empty() {
            text.push(Piece::Text(" (".into()));
            for (n, &s) in prev.iter().enumerate() {
                if n > 0 {
                    text.push(Piece::Text(", ".into()));
                }
                let name = self.sites.get(s).map_or("?", |site| site.task.as_str());
                text.push(Piece::Site(s, name.to_string()));
            }
            text.push(Piece::Text(")".into()));
        }
        text
    }
}

/// A constraint in canonical TDL spelling (`tdl_syntax::print`), tags resolved.
fn constraint_text(kind: &ConstraintKind, scope: &Scope<'_, '_>, prev: &[usize]) -> Text {
    let mut out = Linked {
        scope,
        prev,
        text: Vec::new(),
    };
    print::constraint(kind, &mut out);
    out.text
}

/// A trigger without its tag, for an edge's label: `terminate at execution completed`.
fn when_label(when: &When, then: Then) -> String {
    let mut out = Label(String::new());
    print::trigger(when, then, &mut out);
    out.0
}

/// Text with references: a tag names the sites it resolves to, `previous` (written or implied)
/// the sites it may be, a task its page.
struct Linked<'x, 's, 'a> {
    scope: &'x Scope<'s, 'a>,
    prev: &'x [usize],
    text: Text,
}

impl print::Sink for Linked<'_, '_, '_> {
    fn text(&mut self, text: &str) {
        match self.text.last_mut() {
            Some(Piece::Text(last)) => last.push_str(text),
            _ => self.text.push(Piece::Text(text.to_owned())),
        }
    }

    fn tag(&mut self, it: &Tag) {
        let text = self.scope.tag_text(it, self.prev);
        self.text.extend(text);
    }

    fn implied_previous(&mut self) {
        self.text(" ");
        let text = self.scope.previous_text(self.prev);
        self.text.extend(text);
    }

    fn task(&mut self, name: &str) {
        self.text.push(Piece::Task(name.to_owned()));
    }
}

/// Plain text with the tags left out.
struct Label(String);

impl print::Sink for Label {
    fn text(&mut self, text: &str) {
        let text = match text.strip_prefix(' ') {
            Some(rest) if self.0.ends_with(' ') => rest,
            _ => text,
        };
        self.0.push_str(text);
    }

    fn tag(&mut self, _: &Tag) {}
}
