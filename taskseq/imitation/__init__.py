"""Training data beyond the logged demonstrations, from the demonstrator of the training scenarios.

`expert` answers "what would the demonstrator do next from here?", `starts`
chains training programs so that one starts where another ended, and
`dagger` rolls a learned planner out and labels the states it reaches. All of
it sees only the scenarios it is handed: a fold's training scenarios.
"""
