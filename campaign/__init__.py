"""Campaign engine: configuration, designs, runner, storage and the command line."""
