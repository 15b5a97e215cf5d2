-- A checksum per pending row (coordinator/src/db/checksum.rs), written with the row: a
-- result received but not yet applied is applied on resume, so a changed outcome there
-- would change the library silently. The resume and `verify` refuse a row that does not
-- match it. Rows written before this migration have none (NULL) and are not checked.
ALTER TABLE pending ADD COLUMN checksum INTEGER;
