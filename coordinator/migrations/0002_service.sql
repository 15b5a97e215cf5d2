-- The service's working state (docs/database.md): candidates of each run's current step
-- that are not yet applied to the library but have a result, or have lost a lease (so
-- their attempts survive a restart); and the worker sessions the coordinator has seen.
-- Candidates merely waiting or leased live in memory, and genomes are not repeated here:
-- a restart redraws or rebreeds every candidate identically from its seed; once applied,
-- a candidate's genome is in `candidates`.

CREATE TABLE pending (
    run_id      INTEGER NOT NULL REFERENCES runs (id),
    number      INTEGER NOT NULL,          -- candidate number in its run
    generation  INTEGER NOT NULL,          -- 0 = initial population
    status      TEXT NOT NULL CHECK (status IN ('waiting', 'done', 'failed')), -- waiting: lost a lease
    attempts    INTEGER NOT NULL DEFAULT 0, -- leases lost to dead or silent workers
    worker      INTEGER REFERENCES workers (id), -- who sent the result, or lost the lease
    outcome     TEXT,                      -- JSON outcome once done or failed
    seconds     REAL,                      -- wall time the evaluation took on the worker
    PRIMARY KEY (run_id, number)
);

CREATE TABLE workers (
    id               INTEGER PRIMARY KEY,  -- one per connection (a reconnecting worker is new)
    name             TEXT NOT NULL,        -- what the worker calls itself (host, pid)
    build            TEXT NOT NULL,
    slots            INTEGER NOT NULL,
    connected_at     TEXT NOT NULL,        -- RFC 3339, UTC
    disconnected_at  TEXT,
    results          INTEGER NOT NULL DEFAULT 0,
    left_because     TEXT
);

-- The library keeps only which candidate holds each cell: the elite's genome is its
-- candidate's genome with the controller of its outcome (the tuned one under ES), so
-- storing it again cost every improvement another copy of the genome. `elites` stays
-- readable as before, as a view.
CREATE TABLE cells (
    run_id      INTEGER NOT NULL REFERENCES runs (id),
    cell        INTEGER NOT NULL,
    candidate   INTEGER NOT NULL,          -- candidates.number in the same run
    fitness     REAL NOT NULL,
    PRIMARY KEY (run_id, cell)
);
INSERT INTO cells (run_id, cell, candidate, fitness)
    SELECT run_id, cell, candidate, fitness FROM elites;
DROP TABLE elites;
CREATE VIEW elites (run_id, cell, candidate, fitness, genome) AS
    SELECT l.run_id, l.cell, l.candidate, l.fitness,
           json_set(c.genome, '$.controller', json_extract(c.outcome, '$.controller'))
    FROM cells l JOIN candidates c ON c.run_id = l.run_id AND c.number = l.candidate;
