//! AAM fitting and tracking. Being written: see issue 5.
