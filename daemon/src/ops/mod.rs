//! Operations on the whole database that an operator (or a timer) starts:
//! imports and their journal, backup and restore, recounting. Each runs
//! beside the service, under the store's locks (`docs/ARCHITECTURE.md`).

pub mod backup;
pub mod import_csv;
pub mod import_journal;
pub mod recount;
