"""Commands beside the stages: the benches (`make bench`, two checkouts side by side, each
learner's cost per sample, the stages' times) and the 1 / W rate rule. Run as
`python -m pipeline.tools.<name>`."""
