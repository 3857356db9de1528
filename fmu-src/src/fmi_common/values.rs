//! The typed get/set paths: one [`Access`] type per FMI getter/setter family converts
//! between the C value type and the model's `f64`; the instance resolves the value
//! references, checks types and states against the table and reads, or writes
//! all-or-nothing.

use std::ffi::c_int;

use super::instance::Instance;
use super::logging::Status;
use super::state_machine::{settable_in, States, Version};
use crate::contract::ModelContract;
use crate::variables::{Causality, VarType, Variability, Variable};

/// Conversions between a C value type and the model's `f64`, and which variable
/// types the accessor serves. One zero-sized type per FMI getter/setter family.
pub(crate) trait Access {
    type C: Copy;
    /// The FMI type name in messages ("Real", "Float64", ...).
    const NAME: &'static str;
    /// The variable types the accessor serves, as [`type_bit`]s.
    const SERVES: u8;
    fn to_c(v: f64) -> Self::C;
    fn from_c(c: Self::C) -> f64;
}

macro_rules! access {
    ($(#[$doc:meta])* $name:ident, $c:ty, $label:literal, $serves:expr, $to:expr, $from:expr) => {
        $(#[$doc])*
        pub(crate) struct $name;
        impl Access for $name {
            type C = $c;
            const NAME: &'static str = $label;
            const SERVES: u8 = $serves;
            fn to_c(v: f64) -> $c {
                ($to)(v)
            }
            fn from_c(c: $c) -> f64 {
                ($from)(c)
            }
        }
    };
}

// Values are exact: enumeration values and Booleans are small integers stored in f64.
access!(Real2, f64, "Real", REAL, |v| v, |c| c);
access!(
    /// fmi2Integer serves enumerations (FMI 2 has no separate enumeration accessor).
    Integer2, c_int, "Integer", ENUMERATION, |v: f64| v as c_int, |c: c_int| c as f64
);
access!(
    Boolean2,
    c_int,
    "Boolean",
    BOOLEAN,
    |v: f64| (v != 0.0) as c_int,
    |c: c_int| (c != 0) as u8 as f64
);
access!(Float64, f64, "Float64", REAL, |v| v, |c| c);
access!(
    /// FMI 3 enumerations are Int64.
    Int64, i64, "Int64", ENUMERATION, |v: f64| v as i64, |c: i64| c as f64
);
access!(
    /// fmi3Boolean is C `bool`; read as a byte so a non-0/1 byte from C is no UB.
    Boolean3, u8, "Boolean", BOOLEAN, |v: f64| (v != 0.0) as u8, |c: u8| (c != 0) as u8 as f64
);
// FMI 3 types this FMU has no variables of: every value reference is refused.
access!(Float32, f32, "Float32", 0, |v: f64| v as f32, |c: f32| c as f64);
access!(Int8, i8, "Int8", 0, |v: f64| v as i8, |c: i8| c as f64);
access!(UInt8, u8, "UInt8", 0, |v: f64| v as u8, |c: u8| c as f64);
access!(Int16, i16, "Int16", 0, |v: f64| v as i16, |c: i16| c as f64);
access!(UInt16, u16, "UInt16", 0, |v: f64| v as u16, |c: u16| c as f64);
access!(Int32, i32, "Int32", 0, |v: f64| v as i32, |c: i32| c as f64);
access!(UInt32, u32, "UInt32", 0, |v: f64| v as u32, |c: u32| c as f64);
access!(UInt64, u64, "UInt64", 0, |v: f64| v as u64, |c: u64| c as f64);

// The variable types, one bit each, for the accessors' `SERVES` and the access table.
const REAL: u8 = 1;
const BOOLEAN: u8 = 2;
const ENUMERATION: u8 = 4;

const fn type_bit(ty: VarType) -> u8 {
    match ty {
        VarType::Real => REAL,
        VarType::Boolean => BOOLEAN,
        VarType::Enumeration(_) => ENUMERATION,
    }
}

/// The most variables a model may have for [`access_table`].
const MAX_VARIABLES: usize = 256;

/// What the getters and setters check of a variable on every call, precomputed from the
/// model's table: its type (a [`type_bit`]) and the states it may be set in. Rows past the
/// table's end serve no type, so their references are refused as unknown.
#[derive(Clone, Copy)]
struct VariableAccess {
    type_bit: u8,
    settable: States,
}

const fn access_table(variables: &[Variable]) -> [VariableAccess; MAX_VARIABLES] {
    assert!(variables.len() <= MAX_VARIABLES, "more variables than MAX_VARIABLES");
    let none = VariableAccess { type_bit: 0, settable: States::NONE };
    let mut table = [none; MAX_VARIABLES];
    let mut i = 0;
    while i < variables.len() {
        let settable = match settable_in(&variables[i]) {
            Some(states) => states,
            None => States::NONE,
        };
        table[i] = VariableAccess { type_bit: type_bit(variables[i].ty), settable };
        i += 1;
    }
    table
}

/// For one accessor, the states in which each variable may be set through it, by value
/// reference: [`settable_in`] where the accessor serves the variable's type, no state
/// otherwise. A setter's check of a reference is then one look-up and one bit test.
const fn settable_through(
    access: &[VariableAccess; MAX_VARIABLES],
    serves: u8,
) -> [States; MAX_VARIABLES] {
    let mut table = [States::NONE; MAX_VARIABLES];
    let mut i = 0;
    while i < MAX_VARIABLES {
        if access[i].type_bit & serves != 0 {
            table[i] = access[i].settable;
        }
        i += 1;
    }
    table
}

/// The look-up tables of one model and accessor.
struct AccessTables<M, A>(std::marker::PhantomData<(M, A)>);

impl<M: ModelContract, A: Access> AccessTables<M, A> {
    const SETTABLE: &'static [States; MAX_VARIABLES] =
        &settable_through(Instance::<M>::ACCESS, A::SERVES);
}

/// Type name of a variable as the given FMI version spells it.
fn type_label(ty: VarType, version: Version) -> String {
    match (ty, version) {
        (VarType::Real, Version::Fmi2) => "Real".into(),
        (VarType::Real, Version::Fmi3) => "Float64".into(),
        (VarType::Boolean, _) => "Boolean".into(),
        (VarType::Enumeration(e), Version::Fmi2) => {
            format!("Enumeration {e} (use fmi2GetInteger/fmi2SetInteger)")
        }
        (VarType::Enumeration(e), Version::Fmi3) => {
            format!("Enumeration {e} (use fmi3GetInt64/fmi3SetInt64)")
        }
    }
}

impl<M: ModelContract> Instance<M> {
    /// The getters' and setters' view of the model's variables, indexed by value reference.
    const ACCESS: &'static [VariableAccess; MAX_VARIABLES] = &access_table(M::VARIABLES);

    /// The index of value reference `vr` if it names a variable of a type the accessor serves.
    #[inline]
    fn resolve<A: Access>(&self, vr: u32) -> Result<usize, Status> {
        if Self::serves::<A>(vr) {
            return Ok(vr as usize);
        }
        self.refuse_reference(vr, A::NAME)
    }

    /// Whether value reference `vr` names a variable of a type the accessor serves.
    #[inline]
    fn serves<A: Access>(vr: u32) -> bool {
        Self::ACCESS.get(vr as usize).is_some_and(|access| access.type_bit & A::SERVES != 0)
    }

    /// Error for a value reference that is unknown or not of the accessor's type.
    #[cold]
    fn refuse_reference<T>(&self, vr: u32, accessor: &str) -> Result<T, Status> {
        let Some(var) = M::VARIABLES.get(vr as usize) else {
            return self.error(&format!("unknown value reference {vr}"));
        };
        self.error(&format!(
            "value reference {vr} is {} of type {}, not {accessor}",
            var.name,
            type_label(var.ty, self.version)
        ))
    }

    /// Checks that every reference names a variable of a type the accessor serves that may
    /// be set in the current state (the table's [`settable_in`]): one look-up per reference.
    #[inline]
    fn check_settable<A: Access>(&self, vrs: &[u32]) -> Result<(), Status> {
        let (table, now) = (AccessTables::<M, A>::SETTABLE, self.state);
        let settable = |vr: u32| table.get(vr as usize).is_some_and(|states| states.contains(now));
        if vrs.iter().all(|&vr| settable(vr)) {
            return Ok(());
        }
        self.refuse_to_set::<A>(vrs)
    }

    /// Error for the first reference [`Instance::check_settable`] refused: unknown or of
    /// another type first, then not settable now.
    #[cold]
    #[inline(never)]
    fn refuse_to_set<A: Access>(&self, vrs: &[u32]) -> Result<(), Status> {
        for &vr in vrs {
            let index = self.resolve::<A>(vr)?;
            if !AccessTables::<M, A>::SETTABLE[index].contains(self.state) {
                return self.refuse_setting(index);
            }
        }
        Ok(())
    }

    /// Error for setting variable `index`, which [`Instance::check_settable`] refused.
    #[cold]
    #[inline(never)]
    fn refuse_setting(&self, index: usize) -> Result<(), Status> {
        let var = &M::VARIABLES[index];
        let Some(allowed) = settable_in(var) else {
            let kind = match var.causality {
                Causality::Output => "an output",
                Causality::CalculatedParameter => {
                    "a calculated parameter (worked out from the parameters at initialisation)"
                }
                _ => "the independent variable",
            };
            return self.error(&format!("{} is {kind} and cannot be set", var.name));
        };
        let kind = match (var.causality, var.variability) {
            (Causality::Input, _) => "an input",
            (_, Variability::Fixed) => {
                "a fixed parameter (structure or hardware): it can be set only before \
                 initialisation ends (or after Reset); the tunable parameters and the \
                 inputs can be set during the run"
            }
            _ => "a tunable parameter",
        };
        self.error(&format!(
            "{} is {kind}; it cannot be set in state {} (only in {})",
            var.name,
            self.state.name(self.version),
            allowed.names(self.version)
        ))
    }

    /// Typed getter shared by `fmi2GetReal/Integer/Boolean` and `fmi3Get<numeric>/Boolean`.
    /// FMI 2 passes `n_values = n_vr`.
    ///
    /// # Safety
    /// Array contracts of [`Instance::slice`] / [`Instance::slice_mut`].
    pub(crate) unsafe fn get_values<A: Access>(
        &mut self,
        vrs: *const u32,
        n_vr: usize,
        values: *mut A::C,
        n_values: usize,
    ) -> Result<Status, Status> {
        if n_values != n_vr {
            return self.error(&format!(
                "nValues = {n_values} but the {n_vr} value references (all scalars) need {n_vr}"
            ));
        }
        // SAFETY: forwarded array contracts.
        let (vrs, out) = unsafe { self.value_arrays_mut(vrs, values, n_vr)? };
        // The values before a refused reference are read, as they always were.
        let mut read = self.model.reader();
        for (&vr, slot) in vrs.iter().zip(out.iter_mut()) {
            if !Self::serves::<A>(vr) {
                drop(read);
                return self.refuse_reference(vr, A::NAME);
            }
            *slot = A::to_c(read(vr as usize));
        }
        Ok(Status::OK)
    }

    /// Typed setter: all references, types and states are checked first; values are
    /// then applied all-or-nothing (the model is untouched on any error).
    ///
    /// # Safety
    /// Array contracts of [`Instance::slice`].
    pub(crate) unsafe fn set_values<A: Access>(
        &mut self,
        vrs: *const u32,
        n_vr: usize,
        values: *const A::C,
        n_values: usize,
    ) -> Result<Status, Status> {
        if n_values != n_vr {
            return self.error(&format!(
                "nValues = {n_values} but the {n_vr} value references (all scalars) need {n_vr}"
            ));
        }
        // SAFETY: forwarded array contracts.
        let (vrs, vals) = unsafe { self.value_arrays(vrs, values, n_vr)? };
        self.check_settable::<A>(vrs)?;
        // All or nothing; tunable parameters set in Step Mode rebuild the physics here.
        let result = self
            .model
            .set_values(vrs.iter().zip(vals).map(|(&vr, &c)| (vr as usize, A::from_c(c))));
        match result {
            Ok(()) => Ok(Status::OK),
            Err(e) => self.error(&e),
        }
    }

    /// `fmi2SetRealInputDerivatives`: all references checked first (Real inputs, settable
    /// now), then the derivatives set all-or-nothing.
    ///
    /// # Safety
    /// Array contracts of [`Instance::slice`].
    pub(crate) unsafe fn set_input_derivatives(
        &mut self,
        vrs: *const u32,
        n_vr: usize,
        orders: *const c_int,
        values: *const f64,
    ) -> Result<Status, Status> {
        // SAFETY: forwarded array contracts.
        let (vrs, orders, values) = unsafe {
            (
                self.slice("valueReferences", vrs, n_vr)?,
                self.slice("order", orders, n_vr)?,
                self.slice("value", values, n_vr)?,
            )
        };
        self.check_settable::<Real2>(vrs)?;
        let mut model = self.model.clone();
        for ((&vr, &order), &value) in vrs.iter().zip(orders).zip(values) {
            if let Err(e) = model.set_input_derivative(vr as usize, order, value) {
                return self.error(&e);
            }
        }
        self.model = model;
        Ok(Status::OK)
    }

    /// `fmi2GetRealOutputDerivatives` / `fmi3GetOutputDerivatives`: the derivatives of
    /// real outputs at the current communication point.
    ///
    /// # Safety
    /// Array contracts of [`Instance::slice`] / [`Instance::slice_mut`].
    pub(crate) unsafe fn get_output_derivatives<A: Access>(
        &self,
        vrs: *const u32,
        n_vr: usize,
        orders: *const c_int,
        values: *mut f64,
        n_values: usize,
    ) -> Result<Status, Status> {
        if n_values != n_vr {
            return self.error(&format!(
                "nValues = {n_values} but the {n_vr} value references (all scalars) need {n_vr}"
            ));
        }
        // SAFETY: forwarded array contracts.
        let (vrs, orders, out) = unsafe {
            (
                self.slice("valueReferences", vrs, n_vr)?,
                self.slice("orders", orders, n_vr)?,
                self.slice_mut("values", values, n_values)?,
            )
        };
        for ((&vr, &order), slot) in vrs.iter().zip(orders).zip(out.iter_mut()) {
            let index = self.resolve::<A>(vr)?;
            *slot = match self.model.output_derivative(index, order) {
                Ok(value) => value,
                Err(e) => return self.error(&e),
            };
        }
        Ok(Status::OK)
    }

    /// Get/Set of a type with no variables (strings, binaries, clocks): only `n_vr = 0`
    /// succeeds; every reference is refused as unknown or of another type.
    ///
    /// # Safety
    /// Array contract of [`Instance::slice`] for `vrs`.
    pub(crate) unsafe fn no_values(
        &self,
        type_name: &str,
        vrs: *const u32,
        n_vr: usize,
        n_values: Option<usize>,
    ) -> Result<Status, Status> {
        if let Some(n) = n_values.filter(|&n| n != n_vr) {
            return self.error(&format!(
                "nValues = {n} but the {n_vr} value references (all scalars) need {n_vr}"
            ));
        }
        // SAFETY: forwarded array contract.
        let vrs = unsafe { self.slice("valueReferences", vrs, n_vr)? };
        for &vr in vrs {
            self.refuse_reference::<()>(vr, type_name)?;
        }
        Ok(Status::OK)
    }
}
