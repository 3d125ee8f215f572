//! Expression cloning (section 3 of the paper). Being written: see issue 3.
