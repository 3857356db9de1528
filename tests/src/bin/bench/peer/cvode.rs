//! The few SUNDIALS CVODE functions the peer calls (SUNDIALS 6.x C API), resolved at run
//! time from `libsundials_cvode.so.6` (Debian: libsundials-cvode6, which also carries the
//! serial N_Vector, the dense SUNMatrix and the dense SUNLinearSolver). Loading at run time
//! keeps the benchmark building and running (without the peer) where SUNDIALS is absent.

use std::ffi::{c_int, c_long, c_void};

pub type NVector = *mut c_void;
type Ctx = *mut c_void;
type Matrix = *mut c_void;
type LinSol = *mut c_void;
/// `sunindextype` (64-bit in Debian's build; the values passed are tiny either way).
type Index = i64;
pub type RhsFn = unsafe extern "C" fn(f64, NVector, NVector, *mut c_void) -> c_int;

const CV_BDF: c_int = 2;
const CV_NORMAL: c_int = 1;

/// Shared-library names tried in order.
const LIBRARIES: [&str; 2] = ["libsundials_cvode.so.6", "libsundials_cvode.so"];

#[allow(clippy::type_complexity)]
pub struct Api {
    context_create: unsafe extern "C" fn(*mut c_void, *mut Ctx) -> c_int,
    context_free: unsafe extern "C" fn(*mut Ctx) -> c_int,
    new_serial: unsafe extern "C" fn(Index, Ctx) -> NVector,
    destroy: unsafe extern "C" fn(NVector),
    pub array: unsafe extern "C" fn(NVector) -> *mut f64,
    dense_matrix: unsafe extern "C" fn(Index, Index, Ctx) -> Matrix,
    mat_destroy: unsafe extern "C" fn(Matrix),
    linsol_dense: unsafe extern "C" fn(NVector, Matrix, Ctx) -> LinSol,
    linsol_free: unsafe extern "C" fn(LinSol) -> c_int,
    create: unsafe extern "C" fn(c_int, Ctx) -> *mut c_void,
    init: unsafe extern "C" fn(*mut c_void, RhsFn, f64, NVector) -> c_int,
    reinit: unsafe extern "C" fn(*mut c_void, f64, NVector) -> c_int,
    sv_tolerances: unsafe extern "C" fn(*mut c_void, f64, NVector) -> c_int,
    set_linear_solver: unsafe extern "C" fn(*mut c_void, LinSol, Matrix) -> c_int,
    set_user_data: unsafe extern "C" fn(*mut c_void, *mut c_void) -> c_int,
    set_max_num_steps: unsafe extern "C" fn(*mut c_void, c_long) -> c_int,
    set_stop_time: unsafe extern "C" fn(*mut c_void, f64) -> c_int,
    cvode: unsafe extern "C" fn(*mut c_void, f64, NVector, *mut f64, c_int) -> c_int,
    counter: [unsafe extern "C" fn(*mut c_void, *mut c_long) -> c_int; 4],
    cvode_free: unsafe extern "C" fn(*mut *mut c_void),
    _lib: libloading::Library,
}

impl Api {
    pub fn load() -> Result<Api, String> {
        let mut errors = Vec::new();
        let lib = LIBRARIES
            .iter()
            // SAFETY: the SUNDIALS library has no initialisers with preconditions.
            .find_map(|name| match unsafe { libloading::Library::new(name) } {
                Ok(lib) => Some(lib),
                Err(e) => {
                    errors.push(e.to_string());
                    None
                }
            })
            .ok_or_else(|| format!("SUNDIALS CVODE not found ({})", errors.join("; ")))?;
        macro_rules! sym {
            ($name:literal) => {{
                // SAFETY: the symbol has the SUNDIALS 6 signature of the field it fills.
                let s = unsafe { lib.get($name) }.map_err(|e| e.to_string())?;
                *s
            }};
        }
        Ok(Api {
            context_create: sym!(b"SUNContext_Create\0"),
            context_free: sym!(b"SUNContext_Free\0"),
            new_serial: sym!(b"N_VNew_Serial\0"),
            destroy: sym!(b"N_VDestroy\0"),
            array: sym!(b"N_VGetArrayPointer\0"),
            dense_matrix: sym!(b"SUNDenseMatrix\0"),
            mat_destroy: sym!(b"SUNMatDestroy\0"),
            linsol_dense: sym!(b"SUNLinSol_Dense\0"),
            linsol_free: sym!(b"SUNLinSolFree\0"),
            create: sym!(b"CVodeCreate\0"),
            init: sym!(b"CVodeInit\0"),
            reinit: sym!(b"CVodeReInit\0"),
            sv_tolerances: sym!(b"CVodeSVtolerances\0"),
            set_linear_solver: sym!(b"CVodeSetLinearSolver\0"),
            set_user_data: sym!(b"CVodeSetUserData\0"),
            set_max_num_steps: sym!(b"CVodeSetMaxNumSteps\0"),
            set_stop_time: sym!(b"CVodeSetStopTime\0"),
            cvode: sym!(b"CVode\0"),
            counter: [
                sym!(b"CVodeGetNumSteps\0"),
                sym!(b"CVodeGetNumJacEvals\0"),
                sym!(b"CVodeGetNumLinSolvSetups\0"),
                sym!(b"CVodeGetNumErrTestFails\0"),
            ],
            cvode_free: sym!(b"CVodeFree\0"),
            _lib: lib,
        })
    }
}

/// Work counters of a CVODE run.
#[derive(Clone, Copy, Debug, Default)]
pub struct Counters {
    pub steps: i64,
    pub jacobians: i64,
    /// Newton matrix setups (each one LU factorisation of the dense solver).
    pub lu: i64,
    pub error_test_failures: i64,
}

/// One CVODE integrator: BDF, Newton with the dense direct solver (difference-quotient
/// Jacobian), vector absolute tolerances. Freed on drop.
pub struct Solver<'a> {
    api: &'a Api,
    ctx: Ctx,
    mem: *mut c_void,
    y: NVector,
    atol: NVector,
    matrix: Matrix,
    linsol: LinSol,
    t: f64,
    /// Work before the last restart (CVodeReInit zeroes CVODE's counters).
    before_restart: Counters,
}

fn ok(what: &str, flag: c_int) -> Result<(), String> {
    if flag >= 0 {
        Ok(())
    } else {
        Err(format!("CVODE {what} returned {flag}"))
    }
}

impl<'a> Solver<'a> {
    /// `user_data` must stay valid (and at the same address) for the solver's life.
    pub fn new(
        api: &'a Api,
        rhs: RhsFn,
        user_data: *mut c_void,
        y0: &[f64],
        rtol: f64,
        atol: &[f64],
    ) -> Result<Solver<'a>, String> {
        let n = y0.len() as Index;
        // SAFETY: SUNDIALS 6 calling sequence; every object is created before it is used
        // and freed once in Drop; arrays have n elements.
        unsafe {
            let mut ctx: Ctx = std::ptr::null_mut();
            ok("SUNContext_Create", (api.context_create)(std::ptr::null_mut(), &mut ctx))?;
            let y = (api.new_serial)(n, ctx);
            let atol_v = (api.new_serial)(n, ctx);
            let matrix = (api.dense_matrix)(n, n, ctx);
            let linsol = (api.linsol_dense)(y, matrix, ctx);
            let mem = (api.create)(CV_BDF, ctx);
            let mut s = Solver {
                api,
                ctx,
                mem,
                y,
                atol: atol_v,
                matrix,
                linsol,
                t: 0.0,
                before_restart: Counters::default(),
            };
            if y.is_null()
                || atol_v.is_null()
                || matrix.is_null()
                || linsol.is_null()
                || mem.is_null()
            {
                return Err("CVODE: could not create its objects".into());
            }
            std::slice::from_raw_parts_mut((api.array)(y), y0.len()).copy_from_slice(y0);
            std::slice::from_raw_parts_mut((api.array)(atol_v), y0.len()).copy_from_slice(atol);
            ok("CVodeInit", (api.init)(mem, rhs, 0.0, y))?;
            ok("CVodeSVtolerances", (api.sv_tolerances)(mem, rtol, atol_v))?;
            ok("CVodeSetUserData", (api.set_user_data)(mem, user_data))?;
            ok("CVodeSetLinearSolver", (api.set_linear_solver)(mem, linsol, matrix))?;
            ok("CVodeSetMaxNumSteps", (api.set_max_num_steps)(mem, 1_000_000))?;
            s.t = 0.0;
            Ok(s)
        }
    }

    /// The current state.
    pub fn state(&self) -> &[f64] {
        // SAFETY: y is a live serial vector of the solver's length.
        unsafe { std::slice::from_raw_parts((self.api.array)(self.y), self.len()) }
    }

    fn len(&self) -> usize {
        crate::peer::NY
    }

    /// Restarts the method at the current time from the (possibly changed) state: the
    /// right-hand side jumped (new inputs, a time event).
    pub fn restart(&mut self) -> Result<(), String> {
        self.before_restart = self.counters();
        // SAFETY: live solver and vector.
        unsafe { ok("CVodeReInit", (self.api.reinit)(self.mem, self.t, self.y)) }
    }

    /// Integrates to `t_out` exactly (stop time: never past it).
    pub fn advance_to(&mut self, t_out: f64) -> Result<(), String> {
        let mut t_reached = self.t;
        // SAFETY: live solver; y is its own vector.
        unsafe {
            ok("CVodeSetStopTime", (self.api.set_stop_time)(self.mem, t_out))?;
            ok("CVode", (self.api.cvode)(self.mem, t_out, self.y, &mut t_reached, CV_NORMAL))?;
        }
        self.t = t_out;
        Ok(())
    }

    /// Work since the start, restarts included.
    #[allow(clippy::unnecessary_cast)] // c_long is i32 on some targets
    pub fn counters(&self) -> Counters {
        let mut c = [0 as c_long; 4];
        for (f, out) in self.api.counter.iter().zip(c.iter_mut()) {
            // SAFETY: live solver, writable counter.
            unsafe { f(self.mem, out) };
        }
        let b = &self.before_restart;
        Counters {
            steps: b.steps + c[0] as i64,
            jacobians: b.jacobians + c[1] as i64,
            lu: b.lu + c[2] as i64,
            error_test_failures: b.error_test_failures + c[3] as i64,
        }
    }
}

impl Drop for Solver<'_> {
    fn drop(&mut self) {
        // SAFETY: each object was created in `new` and is freed once, solver first.
        unsafe {
            (self.api.cvode_free)(&mut self.mem);
            (self.api.linsol_free)(self.linsol);
            (self.api.mat_destroy)(self.matrix);
            (self.api.destroy)(self.y);
            (self.api.destroy)(self.atol);
            (self.api.context_free)(&mut self.ctx);
        }
    }
}
