-- Feasible-infeasible search (docs/database.md): every simulated candidate's shortfall
-- against the brief, the infeasible library (per cell, the design nearest the brief among
-- those that miss it), and its counts per generation.

-- What keeps a simulated candidate from the brief, and its figure in the order of outcomes:
-- speed (m/s) for a trial that ran to the end, the time it ended (s) for one that did not.
ALTER TABLE candidates ADD COLUMN shortfall TEXT
    CHECK (shortfall IN ('speed', 'backward', 'fell', 'self_contact', 'unstable'));
ALTER TABLE candidates ADD COLUMN standing REAL;
-- What the candidate did to the infeasible library (NULL: not placed there).
ALTER TABLE candidates ADD COLUMN infeasible_placement TEXT
    CHECK (infeasible_placement IN ('new', 'improved', 'discarded'));

-- Candidates stored before this migration: their shortfall and figure, from the outcome.
UPDATE candidates SET
    shortfall = CASE
        WHEN kind = 'rejected' AND json_type(outcome, '$.stats') = 'object' THEN
            CASE WHEN json_extract(outcome, '$.stats.distance') > 0 THEN 'speed' ELSE 'backward' END
        WHEN kind = 'invalid' THEN
            CASE json_extract(outcome, '$.reason.kind')
                WHEN 'no_forward_progress' THEN 'backward'
                WHEN 'self_contact' THEN 'self_contact'
                WHEN 'non_finite' THEN 'unstable'
                WHEN 'blow_up' THEN 'unstable'
            END
    END,
    standing = CASE
        WHEN kind = 'rejected' AND json_type(outcome, '$.stats') = 'object' THEN
            json_extract(outcome, '$.stats.speed')
        WHEN kind = 'invalid' AND json_extract(outcome, '$.reason.kind') = 'no_forward_progress' THEN
            json_extract(outcome, '$.reason.distance') / json_extract(outcome, '$.at_time')
        WHEN kind = 'invalid' AND json_extract(outcome, '$.reason.kind') IN ('self_contact', 'non_finite', 'blow_up') THEN
            json_extract(outcome, '$.at_time')
    END
WHERE kind <> 'valid';

CREATE TABLE infeasible_cells (
    run_id      INTEGER NOT NULL REFERENCES runs (id),
    cell        INTEGER NOT NULL,
    candidate   INTEGER NOT NULL,          -- candidates.number in the same run
    shortfall   TEXT NOT NULL CHECK (shortfall IN ('speed', 'backward', 'fell', 'self_contact', 'unstable')),
    standing    REAL NOT NULL,             -- speed (speed, backward) or end time (the others)
    PRIMARY KEY (run_id, cell)
);

CREATE VIEW infeasible_elites (run_id, cell, candidate, shortfall, standing, genome) AS
    SELECT l.run_id, l.cell, l.candidate, l.shortfall, l.standing,
           json_set(c.genome, '$.controller', json_extract(c.outcome, '$.controller'))
    FROM infeasible_cells l JOIN candidates c ON c.run_id = l.run_id AND c.number = l.candidate;

ALTER TABLE generations ADD COLUMN infeasible_elites INTEGER NOT NULL DEFAULT 0;
ALTER TABLE generations ADD COLUMN infeasible_only INTEGER NOT NULL DEFAULT 0;
ALTER TABLE generations ADD COLUMN infeasible_new INTEGER NOT NULL DEFAULT 0;
ALTER TABLE generations ADD COLUMN infeasible_improved INTEGER NOT NULL DEFAULT 0;

-- An experiment stored before this migration ran the paper's method: say so, so that it
-- resumes as it began (a new experiment's definition names its method).
UPDATE experiment SET definition = definition || char(10) || '[search]' || char(10)
    || 'constraints = "reject"' || char(10)
WHERE definition NOT LIKE '%[search]%';
