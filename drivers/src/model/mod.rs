//! Robot models from DH tables.
