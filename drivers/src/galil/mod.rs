//! The Galil DMC motion controller over a serial line.
