//! Operations on the whole database that an operator (or a timer) starts:
//! imports and their journal, backup and restore, recounting, and the
//! service's health as `phyllo status` judges it. Each runs beside the
//! service, under the store's locks (`docs/ARCHITECTURE.md`).

pub mod backup;
pub mod health;
pub mod import;
pub mod import_csv;
pub mod import_journal;
pub mod recount;
