"""The agent lifecycle machine (transitions), built from trees/agent.yaml."""
