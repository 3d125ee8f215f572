//! facemimic's integration tests: one binary (the library is linked once), a module per area,
//! in the manner of tiny-skia's `tests/integration`. Filter by area with the module path:
//!
//! ```text
//! cargo test --test integration                    # all of them
//! cargo test --test integration expression::       # one area
//! cargo test --target wasm32-unknown-unknown --test integration   # the portable ones, under Node
//! ```
//!
//! The modules that read files, spawn nothing portable or measure allocations are native only;
//! the others are `wasm_bindgen_test`s that also run natively.

mod clone;
mod core;
mod format;
mod fuzz;
mod select;
mod wasm_bench;

#[cfg(not(target_arch = "wasm32"))]
mod canonical;
#[cfg(not(target_arch = "wasm32"))]
mod composite;
#[cfg(not(target_arch = "wasm32"))]
mod composite_measure;
#[cfg(not(target_arch = "wasm32"))]
mod confidence;
#[cfg(not(target_arch = "wasm32"))]
mod enrol;
#[cfg(not(target_arch = "wasm32"))]
mod enrol_bad_input;
#[cfg(not(target_arch = "wasm32"))]
mod enrol_quality;
#[cfg(not(target_arch = "wasm32"))]
mod enrol_webcam;
#[cfg(not(target_arch = "wasm32"))]
mod expression;
#[cfg(not(target_arch = "wasm32"))]
mod find;
#[cfg(not(target_arch = "wasm32"))]
mod fit;
#[cfg(not(target_arch = "wasm32"))]
mod follow;
#[cfg(not(target_arch = "wasm32"))]
mod golden;
#[cfg(not(target_arch = "wasm32"))]
mod hostile;
#[cfg(not(target_arch = "wasm32"))]
mod no_face;
#[cfg(not(target_arch = "wasm32"))]
mod observed;
#[cfg(not(target_arch = "wasm32"))]
mod realdata;
#[cfg(not(target_arch = "wasm32"))]
mod refine;
#[cfg(not(target_arch = "wasm32"))]
mod track_policy;
#[cfg(not(target_arch = "wasm32"))]
mod tracking;

#[cfg(not(target_arch = "wasm32"))]
#[global_allocator]
static ALLOC: counting::Counting = counting::Counting;

/// The binary's global allocator (native): the system's, counting on request for the thread
/// that asks, two ways.
/// - [`peak_during`](counting::peak_during): the peak of bytes live on this thread while a
///   closure runs (the `.fmm` reader's allocation bounds, `format::`).
/// - [`with_engine_counting`](counting::with_engine_counting): this thread's allocations go
///   through the fuzz engine's [`CountingAlloc`](facemimic_testkit::fuzz::CountingAlloc),
///   whose process-wide counters the engine reads for its memory budgets (`fuzz::`). Only that
///   thread's: the tests running beside it would otherwise count too.
///
/// Cheap for every other allocation: a thread-local flag or two.
pub mod counting {
    use std::cell::Cell;

    #[cfg(not(target_arch = "wasm32"))]
    pub use native::*;

    thread_local! {
        static QUIET: Cell<bool> = const { Cell::new(false) };
    }

    /// Silences the panic messages of this thread while alive (a panic hook that lets the
    /// other threads' messages through, so a failure elsewhere still says why).
    pub struct QuietPanics(());

    impl QuietPanics {
        pub fn on_this_thread() -> QuietPanics {
            static HOOK: std::sync::Once = std::sync::Once::new();
            HOOK.call_once(|| {
                let default = std::panic::take_hook();
                std::panic::set_hook(Box::new(move |info| {
                    if !QUIET.try_with(|q| q.get()).unwrap_or(false) {
                        default(info)
                    }
                }));
            });
            QUIET.with(|q| q.set(true));
            QuietPanics(())
        }
    }

    impl Drop for QuietPanics {
        fn drop(&mut self) {
            let _ = QUIET.try_with(|q| q.set(false));
        }
    }

    /// Runs `f` with this thread's allocations counted by the fuzz engine (natively; under
    /// wasm there is no counting allocator and the engine's budgets are not measured).
    pub fn with_engine_counting<T>(f: impl FnOnce() -> T) -> T {
        #[cfg(not(target_arch = "wasm32"))]
        let _on = native::EngineCounting::on();
        f()
    }

    #[cfg(not(target_arch = "wasm32"))]
    mod native {
        use std::alloc::{GlobalAlloc, Layout, System};
        use std::cell::Cell;

        use facemimic_testkit::fuzz::CountingAlloc;

        thread_local! {
            static ON: Cell<bool> = const { Cell::new(false) };
            static LIVE: Cell<isize> = const { Cell::new(0) };
            static PEAK: Cell<isize> = const { Cell::new(0) };
            static ENGINE: Cell<bool> = const { Cell::new(false) };
        }

        fn note(delta: isize) {
            let _ = ON.try_with(|on| {
                if on.get() {
                    let live = LIVE.with(|l| {
                        l.set(l.get() + delta);
                        l.get()
                    });
                    PEAK.with(|p| p.set(p.get().max(live)));
                }
            });
        }

        fn engine() -> bool {
            ENGINE.try_with(|e| e.get()).unwrap_or(false)
        }

        pub struct Counting;

        // Both ways end in `System`: a block may be freed by the other way (another thread's).
        unsafe impl GlobalAlloc for Counting {
            unsafe fn alloc(&self, l: Layout) -> *mut u8 {
                note(l.size() as isize);
                if engine() {
                    unsafe { CountingAlloc.alloc(l) }
                } else {
                    unsafe { System.alloc(l) }
                }
            }
            unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
                note(l.size() as isize);
                if engine() {
                    unsafe { CountingAlloc.alloc_zeroed(l) }
                } else {
                    unsafe { System.alloc_zeroed(l) }
                }
            }
            unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
                note(-(l.size() as isize));
                if engine() {
                    unsafe { CountingAlloc.dealloc(p, l) }
                } else {
                    unsafe { System.dealloc(p, l) }
                }
            }
            unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
                note(new as isize - l.size() as isize);
                if engine() {
                    unsafe { CountingAlloc.realloc(p, l, new) }
                } else {
                    unsafe { System.realloc(p, l, new) }
                }
            }
        }

        /// Runs `f` and returns its result and the peak of bytes allocated (and not yet freed)
        /// on this thread while it ran. The result itself counts (it is alive at the end).
        pub fn peak_during<T>(f: impl FnOnce() -> T) -> (T, usize) {
            LIVE.with(|l| l.set(0));
            PEAK.with(|p| p.set(0));
            ON.with(|o| o.set(true));
            let r = f();
            ON.with(|o| o.set(false));
            (r, PEAK.with(|p| p.get()).max(0) as usize)
        }

        pub(super) struct EngineCounting(());

        impl EngineCounting {
            pub(super) fn on() -> EngineCounting {
                ENGINE.with(|e| e.set(true));
                EngineCounting(())
            }
        }

        impl Drop for EngineCounting {
            fn drop(&mut self) {
                let _ = ENGINE.try_with(|e| e.set(false));
            }
        }
    }
}
