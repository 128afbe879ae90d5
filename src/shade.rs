//! Lit views of normal maps, for people to look at.
