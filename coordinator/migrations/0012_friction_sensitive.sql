-- A walk that holds on one floor only (docs/model.md section 6): with `[trial]
-- friction_margin`, a design feasible at the run's friction and not on a floor with less or
-- more grip is invalid with the reason `friction_sensitive`, a shortfall of its own (next to
-- `step_sensitive`, nearest the brief). As in 0010, the two tables that name the shortfalls
-- are rebuilt with the new one allowed (SQLite's 12-step procedure; the views over them
-- dropped first and made again after). Rows are copied unchanged.

DROP VIEW elites;
DROP VIEW infeasible_elites;

CREATE TABLE candidates_new (
    run_id      INTEGER NOT NULL REFERENCES runs (id),
    number      INTEGER NOT NULL,          -- candidate number in its run
    generation  INTEGER NOT NULL,          -- 0 = initial population
    genome      TEXT NOT NULL,             -- JSON genome file
    outcome     TEXT NOT NULL,             -- JSON outcome (valid/rejected/invalid, stats, reason)
    kind        TEXT NOT NULL CHECK (kind IN ('valid', 'rejected', 'invalid')),
    fitness     REAL,                      -- 1 / COT, valid only
    cell        INTEGER,                   -- library cell, valid only
    placement   TEXT NOT NULL CHECK (placement IN ('new', 'improved', 'discarded', 'rejected', 'invalid')),
    -- What keeps it from the brief, and its figure in the order of outcomes (0003).
    shortfall   TEXT CHECK (shortfall IN ('step_sensitive', 'friction_sensitive', 'speed', 'backward', 'skating', 'fell', 'self_contact', 'unstable')),
    standing    REAL,
    infeasible_placement TEXT CHECK (infeasible_placement IN ('new', 'improved', 'discarded')),
    checksum    INTEGER,                   -- the row's checksum (0006)
    PRIMARY KEY (run_id, number)
);
INSERT INTO candidates_new (run_id, number, generation, genome, outcome, kind, fitness, cell,
        placement, shortfall, standing, infeasible_placement, checksum)
    SELECT run_id, number, generation, genome, outcome, kind, fitness, cell,
        placement, shortfall, standing, infeasible_placement, checksum
    FROM candidates;
DROP TABLE candidates;
ALTER TABLE candidates_new RENAME TO candidates;

CREATE TABLE infeasible_cells_new (
    run_id      INTEGER NOT NULL REFERENCES runs (id),
    cell        INTEGER NOT NULL,
    candidate   INTEGER NOT NULL,          -- candidates.number in the same run
    shortfall   TEXT NOT NULL CHECK (shortfall IN ('step_sensitive', 'friction_sensitive', 'speed', 'backward', 'skating', 'fell', 'self_contact', 'unstable')),
    standing    REAL NOT NULL,             -- speed (speed, backward) or end time (the others)
    PRIMARY KEY (run_id, cell)
);
INSERT INTO infeasible_cells_new (run_id, cell, candidate, shortfall, standing)
    SELECT run_id, cell, candidate, shortfall, standing FROM infeasible_cells;
DROP TABLE infeasible_cells;
ALTER TABLE infeasible_cells_new RENAME TO infeasible_cells;

CREATE VIEW elites (run_id, cell, candidate, fitness, genome) AS
    SELECT l.run_id, l.cell, l.candidate, l.fitness,
           json_set(c.genome, '$.controller', json_extract(c.outcome, '$.controller'))
    FROM cells l JOIN candidates c ON c.run_id = l.run_id AND c.number = l.candidate;

CREATE VIEW infeasible_elites (run_id, cell, candidate, shortfall, standing, genome) AS
    SELECT l.run_id, l.cell, l.candidate, l.shortfall, l.standing,
           json_set(c.genome, '$.controller', json_extract(c.outcome, '$.controller'))
    FROM infeasible_cells l JOIN candidates c ON c.run_id = l.run_id AND c.number = l.candidate;
