-- Strider's database: one experiment, its runs, every evaluated candidate, the library
-- (one elite per occupied cell per run) and per-generation statistics.
-- docs/database.md describes every column.

CREATE TABLE experiment (
    id          INTEGER PRIMARY KEY CHECK (id = 1),
    name        TEXT NOT NULL,
    definition  TEXT NOT NULL,   -- the experiment, as canonical TOML
    build       TEXT NOT NULL,   -- the Strider build that evaluates it
    created_at  TEXT NOT NULL    -- RFC 3339, UTC
);

CREATE TABLE runs (
    id              INTEGER PRIMARY KEY,   -- 0-based, schemes x repeats in file order
    scheme          TEXT NOT NULL CHECK (scheme IN ('static', 'genome', 'es')),
    repeat          INTEGER NOT NULL,
    seed            INTEGER NOT NULL,      -- u64 stored bit-for-bit as i64
    generation      INTEGER NOT NULL,      -- last committed generation; 0 = initial population
    initial_passed  INTEGER NOT NULL,      -- valid candidates in the initial population so far
    next_candidate  INTEGER NOT NULL,      -- first candidate number not yet committed
    finished        INTEGER NOT NULL DEFAULT 0
);

CREATE TABLE candidates (
    run_id      INTEGER NOT NULL REFERENCES runs (id),
    number      INTEGER NOT NULL,          -- candidate number in its run
    generation  INTEGER NOT NULL,          -- 0 = initial population
    genome      TEXT NOT NULL,             -- JSON genome file
    outcome     TEXT NOT NULL,             -- JSON outcome (valid/rejected/invalid, stats, reason)
    kind        TEXT NOT NULL CHECK (kind IN ('valid', 'rejected', 'invalid')),
    fitness     REAL,                      -- 1 / COT, valid only
    cell        INTEGER,                   -- library cell, valid only
    placement   TEXT NOT NULL CHECK (placement IN ('new', 'improved', 'discarded', 'rejected', 'invalid')),
    PRIMARY KEY (run_id, number)
);

CREATE TABLE elites (
    run_id      INTEGER NOT NULL REFERENCES runs (id),
    cell        INTEGER NOT NULL,
    candidate   INTEGER NOT NULL,
    fitness     REAL NOT NULL,
    genome      TEXT NOT NULL,             -- JSON genome with the controller that earned it
    PRIMARY KEY (run_id, cell)
);

CREATE TABLE generations (
    run_id        INTEGER NOT NULL REFERENCES runs (id),
    generation    INTEGER NOT NULL,        -- 0 = initial population
    evaluations   INTEGER NOT NULL,        -- candidates evaluated in this generation
    coverage      REAL NOT NULL,
    elites        INTEGER NOT NULL,
    max_fitness   REAL NOT NULL,
    mean_fitness  REAL NOT NULL,
    min_fitness   REAL NOT NULL,
    qd_score      REAL NOT NULL,
    new           INTEGER NOT NULL,
    improved      INTEGER NOT NULL,
    discarded     INTEGER NOT NULL,
    rejected      INTEGER NOT NULL,
    invalid       INTEGER NOT NULL,
    PRIMARY KEY (run_id, generation)
);
