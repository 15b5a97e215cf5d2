-- A checksum per generations row (coordinator/src/db/checksum.rs), written with the row:
-- the resume refuses a database whose stored per-generation figures no longer match it,
-- and `verify` names the row. Rows written before this migration have none (NULL) and
-- are not checked.
ALTER TABLE generations ADD COLUMN checksum INTEGER;
