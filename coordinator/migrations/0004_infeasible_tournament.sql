-- Infeasible parents by tournament (docs/model.md section 12): an experiment stored before
-- this migration drew them uniformly, so it says so, and resumes as it began (a new
-- experiment's definition names its tournament size).
UPDATE experiment SET definition = replace(definition, '[search]' || char(10),
    '[search]' || char(10) || 'infeasible_tournament = 1' || char(10))
WHERE definition NOT LIKE '%infeasible_tournament%';
