-- The friction margin's floors and the shove became the defaults (`[trial] friction_margin
-- = 0.25`, `push_speed = 0.3`; docs/model.md section 6). An experiment stored without them
-- was run without them, so it says so (0: off) and resumes as it began; one stored since
-- they were settings names its own values. Its row is rewritten, so its checksum is cleared
-- for the next writer to seal (0011). Experiments stored before the fall checks (no [trial]
-- table) are left as they are.
UPDATE experiment SET definition = replace(definition, '[trial]' || char(10),
    '[trial]' || char(10) || 'friction_margin = 0.0' || char(10)), checksum = NULL
WHERE definition LIKE '%[trial]%'
  AND definition NOT LIKE '%friction_margin%';
UPDATE experiment SET definition = replace(definition, '[trial]' || char(10),
    '[trial]' || char(10) || 'push_speed = 0.0' || char(10)), checksum = NULL
WHERE definition LIKE '%[trial]%'
  AND definition NOT LIKE '%push_speed%';
