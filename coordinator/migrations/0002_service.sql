-- The service's working state (docs/database.md): the candidates of each run's current step
-- that are not yet applied to the library, with leases and results as they arrive, and the
-- worker sessions the coordinator has seen.

CREATE TABLE pending (
    run_id      INTEGER NOT NULL REFERENCES runs (id),
    number      INTEGER NOT NULL,          -- candidate number in its run
    generation  INTEGER NOT NULL,          -- 0 = initial population
    genome      TEXT NOT NULL,             -- JSON genome file
    status      TEXT NOT NULL CHECK (status IN ('waiting', 'leased', 'done', 'failed')),
    attempts    INTEGER NOT NULL DEFAULT 0, -- leases lost to dead or silent workers
    worker      INTEGER REFERENCES workers (id), -- holder of the lease, or who sent the result
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
