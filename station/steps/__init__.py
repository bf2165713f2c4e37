"""The job's steps, once: the recipe that the daemon and the console commands both call.

Read one job from `station submit` to its cut record in this order:

0. `submission.check_job`: refuse at submission what could never run (garment, fabric,
   options); the daemon runs it in a bounded child process (`station.intake`).
1. `capture.capture_fabric` -> `Captured`: the operator's FABRIC.json, or a photograph
   from the camera the daemon's caller chose, rectified and read by `vision`.
2. `garment.job_garment` -> `Garment`: the pattern loaded once, in mm, symmetrised if the
   job asks; `garment.grained` adds the job's grain lines and bias pieces.
3. `place.align_job` -> `Placement`: the print aligned across the seams (left/right pairs
   mirrored; `place.align_garment` is the one alignment, `station align` calls it too);
   `place.reshape_placed` optionally nudges the outlines; on plain cloth
   `place.plain_placement` only turns the pieces onto the grain.
4. `nest.nest_placement` -> `solver.nest.layout.Layout`: the verified marker.
5. `program.machine_layout` -> `gcode.layout.Layout`, the one adapter from the solver's
   marker to the machine's; `program.program_of` -> the checked `Program` (`station
   gcode` calls it too).
   `plan.plan_job` runs 2 to 5 and hands back a `records.Plan`; `pictures.draw_plan`
   draws the pictures from it afterwards.
6. `cut.cut_job`: ask the machine what it did while nobody listened, then stream the
   pieces left; each piece is recorded cut in the job store at its sync point.

A marker longer than the table is cut in bites (issue 35): `table.table_window` is the
table window, checked when the pipeline is made; the nest step (`nest.
nest_in_window_or_bites`) nests a marker that does not fit it on the roll and cuts it
into bites (`bites.plan_job_bites`; the `Plan` carries them, bites.json beside
layout.json); the cut step (`cutbites.cut_in_bites`) brings each bite onto the table
(`bites.find_bite`: advance by the profile's conveyor or the operator, photograph,
measure the roll's real advance from the print, `roll.CameraRoll`) and cuts its pieces
where the cloth lies, journalling the bites so that a restart resumes at the right one.

`station.pipeline.StationPipeline` runs these for the daemon (`station.daemon`), whose
state machine records each step's result in the job store before the next begins.
Every step takes a garment (and the job's options) and returns typed objects, so an order
of several garments can call them per garment. Files are written into the job's folder
for the operator and for a job resumed by another process; inside one process nothing is
read back.
"""
