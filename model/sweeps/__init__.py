"""The force sweep: does the generated contact answer the wrench as the real one does? Poses, references, report."""
