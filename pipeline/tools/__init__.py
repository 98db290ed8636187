"""Commands beside the stages: the benches (`make bench`, two checkouts side by side, each
learner's cost per sample, the stages' times), the 1 / W rate rule, the coverage table and the
pages rendered from the report's named values (render). Run as
`python -m pipeline.tools.<name>`."""
