//! Reading height maps and writing normal maps: image files, bytes, atomic writes.
