//! Running a case.
