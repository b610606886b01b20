//! The registry of what interpreted programs call that is implemented outside TDL (docs/
//! language.md, "Running programs without compiling them"): tasks built in Rust, functions,
//! methods and fields of host types, constants. A program is checked against it when it is
//! loaded: a name no registry offers is refused then, with what is offered.
//!
//! Functions are registered as typed Rust closures; their parameters convert from values
//! ([`FromValue`]), their results to values ([`IntoOutcome`]). A conversion that fails when the
//! program runs fails the node with the exception `TypeMismatch`, naming the function, the
//! argument and both types.

use std::any::Any;
use std::collections::{BTreeMap, BTreeSet};
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;

use tdl::{Failure, Task};

use crate::convert::{FromValue, IntoOutcome, IntoValue};
use crate::value::Value;

/// A future a function returns.
pub type BoxFuture = Pin<Box<dyn Future<Output = Result<Value, Failure>> + Send + 'static>>;

/// What calling a registered function gives: its result, or a future of it.
pub enum Call {
    /// The result, at once.
    Ready(Result<Value, Failure>),
    /// A future of the result (an `async` function), which the body awaits.
    Pending(BoxFuture),
}

type CallFn = dyn Fn(&[Value]) -> Call + Send + Sync;

/// A registered function: its parameter count and its body over values.
#[derive(Clone)]
pub struct Function {
    pub(crate) arity: usize,
    pub(crate) params: Vec<String>,
    pub(crate) is_async: bool,
    pub(crate) call: Arc<CallFn>,
}

impl Function {
    /// A function over values, for what the typed registrations cannot say (any number of
    /// arguments, values of any kind).
    pub fn dynamic(
        arity: usize,
        f: impl Fn(&[Value]) -> Result<Value, Failure> + Send + Sync + 'static,
    ) -> Function {
        Function {
            arity,
            params: vec!["any value".into(); arity],
            is_async: false,
            call: Arc::new(move |args| Call::Ready(f(args))),
        }
    }
}

/// The failure of an argument that does not convert.
pub(crate) fn mismatch(what: &str, index: usize, expected: &str, found: &Value) -> Failure {
    Failure::new(
        "TypeMismatch",
        format!(
            "{what}: argument {}: expected {expected}, found {} `{found:?}`",
            index + 1,
            found.kind()
        ),
    )
}

/// A closure that can be registered as a function: `Fn(A, B, ...) -> R` with every parameter
/// [`FromValue`] and `R` [`IntoOutcome`].
pub trait IntoFunction<Marker>: Send + Sync + 'static {
    /// The function, named `what` in messages.
    fn into_function(self, what: String) -> Function;
}

/// An `async` closure that can be registered: `Fn(A, ...) -> impl Future<Output = R>`.
pub trait IntoAsyncFunction<Marker>: Send + Sync + 'static {
    /// The function, named `what` in messages.
    fn into_async_function(self, what: String) -> Function;
}

/// A closure that builds a task: `Fn(A, B, ...) -> tdl::Task`.
pub trait IntoTaskFn<Marker>: Send + Sync + 'static {
    /// The constructor, named `what` in messages.
    fn into_task_fn(self, what: String) -> TaskFn;
}

/// A task constructor over values.
pub type TaskFn = Arc<dyn Fn(&[Value]) -> Result<Task, Failure> + Send + Sync>;

macro_rules! arities {
    ($(($($a:ident $i:tt),*)),*) => {$(
        #[allow(non_snake_case, unused_variables)]
        impl<F, R, $($a,)*> IntoFunction<(R, $($a,)*)> for F
        where
            F: Fn($($a),*) -> R + Send + Sync + 'static,
            R: IntoOutcome,
            $($a: FromValue,)*
        {
            fn into_function(self, what: String) -> Function {
                let n = 0 $(+ { let _ = $i; 1 })*;
                Function {
                    arity: n,
                    params: vec![$($a::expected()),*],
                    is_async: false,
                    call: Arc::new(move |args: &[Value]| {
                        $(
                            let Some($a) = args.get($i).and_then($a::from_value) else {
                                let found = args.get($i).cloned().unwrap_or_default();
                                return Call::Ready(Err(mismatch(&what, $i, &$a::expected(), &found)));
                            };
                        )*
                        Call::Ready(self($($a),*).into_outcome())
                    }),
                }
            }
        }

        #[allow(non_snake_case, unused_variables)]
        impl<F, Fut, R, $($a,)*> IntoAsyncFunction<(R, $($a,)*)> for F
        where
            F: Fn($($a),*) -> Fut + Send + Sync + 'static,
            Fut: Future<Output = R> + Send + 'static,
            R: IntoOutcome,
            $($a: FromValue,)*
        {
            fn into_async_function(self, what: String) -> Function {
                let n = 0 $(+ { let _ = $i; 1 })*;
                Function {
                    arity: n,
                    params: vec![$($a::expected()),*],
                    is_async: true,
                    call: Arc::new(move |args: &[Value]| {
                        $(
                            let Some($a) = args.get($i).and_then($a::from_value) else {
                                let found = args.get($i).cloned().unwrap_or_default();
                                return Call::Ready(Err(mismatch(&what, $i, &$a::expected(), &found)));
                            };
                        )*
                        let fut = self($($a),*);
                        Call::Pending(Box::pin(async move { fut.await.into_outcome() }))
                    }),
                }
            }
        }

        #[allow(non_snake_case, unused_variables)]
        impl<F, $($a,)*> IntoTaskFn<($($a,)*)> for F
        where
            F: Fn($($a),*) -> Task + Send + Sync + 'static,
            $($a: FromValue,)*
        {
            fn into_task_fn(self, what: String) -> TaskFn {
                Arc::new(move |args: &[Value]| {
                    $(
                        let Some($a) = args.get($i).and_then($a::from_value) else {
                            let found = args.get($i).cloned().unwrap_or_default();
                            return Err(mismatch(&what, $i, &$a::expected(), &found));
                        };
                    )*
                    Ok(self($($a),*))
                })
            }
        }
    )*};
}

arities!(
    (),
    (A 0),
    (A 0, B 1),
    (A 0, B 1, C 2),
    (A 0, B 1, C 2, D 3),
    (A 0, B 1, C 2, D 3, E 4),
    (A 0, B 1, C 2, D 3, E 4, G 5)
);

/// How a registered task's value (what its action returned) becomes a value of the program.
pub(crate) type ValueOf = Arc<dyn Fn(Box<dyn Any + Send>) -> Option<Value> + Send + Sync>;

/// A task built in Rust.
#[derive(Clone)]
pub(crate) struct TaskEntry {
    pub(crate) make: TaskFn,
    pub(crate) value: ValueOf,
}

/// A value of a plain type, as tasks built in Rust commonly return them.
fn plain_value(v: Box<dyn Any + Send>) -> Option<Value> {
    macro_rules! try_types {
        ($v:ident, $($t:ty),*) => {
            $(let $v = match $v.downcast::<$t>() {
                Ok(x) => return Some(x.into_value()),
                Err(v) => v,
            };)*
        };
    }
    let v = match v.downcast::<Value>() {
        Ok(x) => return Some(*x),
        Err(v) => v,
    };
    try_types!(
        v,
        (),
        bool,
        i64,
        u64,
        i32,
        u32,
        usize,
        f64,
        String,
        Vec<f64>,
        Vec<u32>,
        Vec<i64>
    );
    let v = match v.downcast::<serde_json::Value>() {
        Ok(j) => return Some(Value::from_json(&j)),
        Err(v) => v,
    };
    drop(v);
    None
}

/// Converts a value of type `T` (the declared result of a task built in Rust).
fn typed_value<T: IntoValue + 'static>(v: Box<dyn Any + Send>) -> Option<Value> {
    v.downcast::<T>().ok().map(|x| x.into_value())
}

/// What programs may call that is implemented outside TDL.
#[derive(Clone, Default)]
pub struct Registry {
    pub(crate) tasks: BTreeMap<String, TaskEntry>,
    pub(crate) functions: BTreeMap<String, Function>,
    pub(crate) methods: BTreeMap<(String, String), Function>,
    pub(crate) fields: BTreeMap<(String, String), Function>,
    pub(crate) constants: BTreeMap<String, Value>,
    pub(crate) host_types: BTreeSet<String>,
    pub(crate) aliases: BTreeMap<String, String>,
    pub(crate) exceptions: BTreeMap<String, Vec<String>>,
}

impl Registry {
    /// An empty registry (the interpreter's built-ins are always there).
    pub fn new() -> Registry {
        Registry::default()
    }

    /// A command built in Rust: `spawn name(args)` calls `f` with the arguments and spawns the
    /// task it returns. Its value, if a body waits for it, is read as a plain value (unit,
    /// numbers, strings, `Value`, JSON); use [`Registry::task_returning`] for another type.
    pub fn task<M>(&mut self, name: &str, f: impl IntoTaskFn<M>) -> &mut Registry {
        self.tasks.insert(
            name.to_string(),
            TaskEntry {
                make: f.into_task_fn(format!("`{name}`")),
                value: Arc::new(plain_value),
            },
        );
        self
    }

    /// A task built in Rust whose value is a `T`.
    pub fn task_returning<T: IntoValue + 'static, M>(
        &mut self,
        name: &str,
        f: impl IntoTaskFn<M>,
    ) -> &mut Registry {
        self.tasks.insert(
            name.to_string(),
            TaskEntry {
                make: f.into_task_fn(format!("`{name}`")),
                value: Arc::new(typed_value::<T>),
            },
        );
        self
    }

    /// A task built in Rust whose value is a `T`, made a value by `convert` (for a type of
    /// another crate: `|path: Vec<Waypoint>| Value::list(path.into_iter().map(|w| Host(w).into_value()))`).
    pub fn task_returning_with<T: 'static, M>(
        &mut self,
        name: &str,
        f: impl IntoTaskFn<M>,
        convert: impl Fn(T) -> Value + Send + Sync + 'static,
    ) -> &mut Registry {
        self.tasks.insert(
            name.to_string(),
            TaskEntry {
                make: f.into_task_fn(format!("`{name}`")),
                value: Arc::new(move |v: Box<dyn Any + Send>| {
                    v.downcast::<T>().ok().map(|x| convert(*x))
                }),
            },
        );
        self
    }

    /// A task built from its arguments as values, for what the typed registrations cannot say
    /// (a task an agent offers, its arguments crossing as JSON); its value is read as a plain
    /// value (JSON included).
    pub fn task_dynamic(
        &mut self,
        name: &str,
        make: impl Fn(&[Value]) -> Result<Task, Failure> + Send + Sync + 'static,
    ) -> &mut Registry {
        self.tasks.insert(
            name.to_string(),
            TaskEntry {
                make: Arc::new(make),
                value: Arc::new(plain_value),
            },
        );
        self
    }

    /// A function, called by its name (a path such as `f64::from` is named as written).
    pub fn function<M>(&mut self, name: &str, f: impl IntoFunction<M>) -> &mut Registry {
        let f = f.into_function(format!("`{name}`"));
        self.functions.insert(name.to_string(), f);
        self
    }

    /// An `async` function: a call of it is followed by `.await` in the program.
    pub fn async_function<M>(&mut self, name: &str, f: impl IntoAsyncFunction<M>) -> &mut Registry {
        let f = f.into_async_function(format!("`{name}`"));
        self.functions.insert(name.to_string(), f);
        self
    }

    /// A function over values, for what typed closures cannot say.
    pub fn dynamic_function(&mut self, name: &str, f: Function) -> &mut Registry {
        self.functions.insert(name.to_string(), f);
        self
    }

    /// A method of the host type `ty`: `x.name(args)` on a value of it calls `f(x, args)`.
    pub fn method<M>(&mut self, ty: &str, name: &str, f: impl IntoFunction<M>) -> &mut Registry {
        let f = f.into_function(format!("`{ty}::{name}`"));
        self.methods.insert((ty.to_string(), name.to_string()), f);
        self
    }

    /// An `async` method of the host type `ty`.
    pub fn async_method<M>(
        &mut self,
        ty: &str,
        name: &str,
        f: impl IntoAsyncFunction<M>,
    ) -> &mut Registry {
        let f = f.into_async_function(format!("`{ty}::{name}`"));
        self.methods.insert((ty.to_string(), name.to_string()), f);
        self
    }

    /// A field of the host type `ty`: `x.name` on a value of it is `f(x)`.
    pub fn field<M>(&mut self, ty: &str, name: &str, f: impl IntoFunction<M>) -> &mut Registry {
        let f = f.into_function(format!("`{ty}.{name}`"));
        self.fields.insert((ty.to_string(), name.to_string()), f);
        self
    }

    /// A constant (a path such as `Costmap::Global` is named as written).
    pub fn constant(&mut self, name: &str, value: impl IntoValue) -> &mut Registry {
        self.constants.insert(name.to_string(), value.into_value());
        self
    }

    /// A host type: programs may name it in parameter and result types, and pass its values
    /// around (make the Rust type one with [`host_type!`](crate::host_type)).
    pub fn host_type(&mut self, name: &str) -> &mut Registry {
        self.host_types.insert(name.to_string());
        self
    }

    /// Another name of a host type (a Rust type alias, `type Waypoint = Point;`): a program
    /// writing `name` means the host type `target`, whose values carry that name.
    pub fn alias(&mut self, name: &str, target: &str) -> &mut Registry {
        self.aliases.insert(name.to_string(), target.to_string());
        self.host_types.insert(target.to_string());
        self
    }

    /// An exception raised by Rust code the program calls, with its ancestors (nearest first),
    /// for programs that handle it without declaring it.
    pub fn exception(&mut self, name: &str, ancestry: &[&str]) -> &mut Registry {
        self.exceptions.insert(
            name.to_string(),
            ancestry.iter().map(|it| (*it).to_string()).collect(),
        );
        self
    }

    /// Everything of `other` added to this registry (its entries win).
    pub fn extend(&mut self, other: &Registry) -> &mut Registry {
        self.tasks.extend(other.tasks.clone());
        self.functions.extend(other.functions.clone());
        self.methods.extend(other.methods.clone());
        self.fields.extend(other.fields.clone());
        self.constants.extend(other.constants.clone());
        self.host_types.extend(other.host_types.iter().cloned());
        self.aliases.extend(other.aliases.clone());
        self.exceptions.extend(other.exceptions.clone());
        self
    }

    /// The names of the tasks it offers, for a message.
    pub fn task_names(&self) -> Vec<&str> {
        self.tasks.keys().map(String::as_str).collect()
    }

    /// The names of the functions it offers, for a message.
    pub fn function_names(&self) -> Vec<&str> {
        self.functions.keys().map(String::as_str).collect()
    }
}
