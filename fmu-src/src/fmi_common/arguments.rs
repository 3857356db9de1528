//! The importer's pointer arguments, checked before they are read: C strings, arrays of
//! the announced length, out-parameters. NULL, misalignment and impossible sizes are
//! refused with an Error naming the argument; the rest is the importer's part of the
//! FMI contract.

use std::ffi::{c_char, CStr};

use super::instance::Instance;
use super::logging::Status;
use crate::contract::ModelContract;

/// Reads a C string argument; `None` for NULL.
///
/// # Safety
/// `p` is NULL or a NUL-terminated string (FMI contract).
pub(crate) unsafe fn opt_str<'a>(p: *const c_char) -> Option<&'a CStr> {
    // SAFETY: see function contract.
    (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) })
}

/// Whether `n` elements at `ptr` may be read as a slice: not NULL, aligned, and at most
/// `isize::MAX` bytes (a bound on `n` fixed at compile time, not a multiplication).
#[inline]
fn usable_array<T>(ptr: *const T, n: usize) -> bool {
    let max_elements = isize::MAX as usize / std::mem::size_of::<T>().max(1);
    !ptr.is_null() && ptr.is_aligned() && n <= max_elements
}

/// Both arrays of a getter's or setter's call usable as slices, and not empty: the tests
/// of [`usable_array`] for both, combined without a branch each.
#[inline]
fn usable_pair<V>(vrs: *const u32, values: *const V, n: usize) -> bool {
    let misaligned = (vrs as usize % align_of::<u32>()) | (values as usize % align_of::<V>());
    let max_elements = isize::MAX as usize / size_of::<u32>().max(size_of::<V>());
    (n != 0) & !vrs.is_null() & !values.is_null() & (misaligned == 0) & (n <= max_elements)
}

impl<M: ModelContract> Instance<M> {
    /// `n` elements at `ptr` as a slice; NULL with `n > 0`, misalignment or an
    /// impossible size → Error naming the argument.
    ///
    /// # Safety
    /// A non-NULL `ptr` points to `n` initialised `T` that stay valid and unaliased by
    /// writes for the call (FMI contract for array arguments).
    pub(crate) unsafe fn slice<'a, T>(
        &self,
        what: &str,
        ptr: *const T,
        n: usize,
    ) -> Result<&'a [T], Status> {
        if n == 0 {
            return Ok(&[]);
        }
        self.check_array(what, ptr, n)?;
        // SAFETY: non-NULL, aligned, size fits isize (checked), validity per contract.
        Ok(unsafe { std::slice::from_raw_parts(ptr, n) })
    }

    /// Mutable variant of [`Instance::slice`] for output arrays.
    ///
    /// # Safety
    /// A non-NULL `ptr` points to `n` writable `T` not otherwise accessed during the call.
    pub(crate) unsafe fn slice_mut<'a, T>(
        &self,
        what: &str,
        ptr: *mut T,
        n: usize,
    ) -> Result<&'a mut [T], Status> {
        if n == 0 {
            return Ok(&mut []);
        }
        self.check_array(what, ptr, n)?;
        // SAFETY: as in `slice`, plus exclusive access per contract. Elements are plain
        // numbers, so writing over possibly uninitialised memory is fine.
        Ok(unsafe { std::slice::from_raw_parts_mut(ptr, n) })
    }

    /// The two arrays of a setter's call, `n` value references and `n` values, as slices.
    /// Both are tested at once (the common case); an empty or refused pair goes through
    /// [`Instance::slice`], which names the first argument at fault.
    ///
    /// # Safety
    /// The contract of [`Instance::slice`] for both.
    #[inline]
    pub(crate) unsafe fn value_arrays<'a, V>(
        &self,
        vrs: *const u32,
        values: *const V,
        n: usize,
    ) -> Result<(&'a [u32], &'a [V]), Status> {
        if usable_pair(vrs, values, n) {
            // SAFETY: both non-NULL, aligned, of a possible size (tested); validity per contract.
            return Ok(unsafe {
                (std::slice::from_raw_parts(vrs, n), std::slice::from_raw_parts(values, n))
            });
        }
        // SAFETY: forwarded contracts.
        unsafe { Ok((self.slice("valueReferences", vrs, n)?, self.slice("values", values, n)?)) }
    }

    /// [`Instance::value_arrays`] of a getter, whose values are written.
    ///
    /// # Safety
    /// The contracts of [`Instance::slice`] for `vrs` and [`Instance::slice_mut`] for `values`.
    #[inline]
    pub(crate) unsafe fn value_arrays_mut<'a, V>(
        &self,
        vrs: *const u32,
        values: *mut V,
        n: usize,
    ) -> Result<(&'a [u32], &'a mut [V]), Status> {
        if usable_pair(vrs, values, n) {
            // SAFETY: as in `value_arrays`, plus exclusive access to `values` per contract.
            return Ok(unsafe {
                (std::slice::from_raw_parts(vrs, n), std::slice::from_raw_parts_mut(values, n))
            });
        }
        // SAFETY: forwarded contracts.
        unsafe {
            Ok((self.slice("valueReferences", vrs, n)?, self.slice_mut("values", values, n)?))
        }
    }

    /// Inlined into every getter and setter: the tests alone; the messages are [`refuse_array`].
    #[inline]
    fn check_array<T>(&self, what: &str, ptr: *const T, n: usize) -> Result<(), Status> {
        if !usable_array(ptr, n) {
            return self.refuse_array(what, ptr.is_null(), ptr.is_aligned(), n);
        }
        Ok(())
    }

    /// Error for an array argument [`Instance::check_array`] refused: NULL first, then
    /// misalignment, then an impossible size.
    #[cold]
    #[inline(never)]
    fn refuse_array(&self, what: &str, null: bool, aligned: bool, n: usize) -> Result<(), Status> {
        self.error(&if null {
            format!("{what} is NULL but {n} elements were announced")
        } else if !aligned {
            format!("{what} is not aligned for its element type")
        } else {
            format!("{what}: {n} elements is not a possible array size")
        })
    }

    /// Out-parameter pointer check.
    ///
    /// # Safety
    /// A non-NULL `ptr` points to a writable `T`.
    pub(crate) unsafe fn out<'a, T>(&self, what: &str, ptr: *mut T) -> Result<&'a mut T, Status> {
        if ptr.is_null() || !ptr.is_aligned() {
            return self.error(&format!("{what} is NULL or misaligned"));
        }
        // SAFETY: non-NULL, aligned, writable per contract; T here is a plain number/pointer.
        Ok(unsafe { &mut *ptr })
    }
}
