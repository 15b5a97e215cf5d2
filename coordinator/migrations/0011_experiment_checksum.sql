-- The experiment row carries a checksum too (as candidates, generations and pending rows
-- do): a changed byte in its definition, name, build or date, which SQLite cannot see,
-- is refused naming the row. Rows stored before this migration have none; the next
-- writer to open the file gives them one.
ALTER TABLE experiment ADD COLUMN checksum INTEGER;
