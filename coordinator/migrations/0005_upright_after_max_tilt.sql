-- A tilt limit for the second after the trial (docs/model.md section 6): an experiment
-- stored before this migration checked the trial's own limit then, so it says so
-- (180 degrees: the trial's limit, the smaller, applies), and resumes as it began.
-- Experiments stored before the fall checks (no [trial] table) are left as they are.
UPDATE experiment SET definition = replace(definition, '[trial]' || char(10),
    '[trial]' || char(10) || 'upright_after_max_tilt_degrees = 180.0' || char(10))
WHERE definition LIKE '%[trial]%'
  AND definition NOT LIKE '%upright_after_max_tilt_degrees%';
