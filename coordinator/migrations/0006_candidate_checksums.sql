-- A checksum per candidate row (coordinator/src/db/checksum.rs): written with the row,
-- checked on resume for the rows the libraries hold and by `verify` for every row. Rows
-- written before this migration have none (NULL) and are not checked.
ALTER TABLE candidates ADD COLUMN checksum INTEGER;
