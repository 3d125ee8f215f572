//! One way to show a value that owns large buffers (pixels, meshes, precomputed matrices) in
//! `{:?}`: its name and the few fields that say what it is, never the buffers.

use std::fmt;

/// Writes `name { field: value, .. }` for `fields`; the `..` marks what is left out.
pub(crate) fn summary(
    f: &mut fmt::Formatter<'_>,
    name: &str,
    fields: &[(&str, &dyn fmt::Debug)],
) -> fmt::Result {
    let mut s = f.debug_struct(name);
    for (key, value) in fields {
        s.field(key, value);
    }
    s.finish_non_exhaustive()
}
