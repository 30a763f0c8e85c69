"""Navigation: costmap, global planner, local planner, goal checks, recoveries, the Navigator
(docs/navigation.md#planning).

Pure skills: data in, data out, time injected. `navigator.Navigator` ties them together for the agent's
go-to-pose leaf; the modules can be used on their own (the dashboard draws `Costmap.cost`, a mission
planner can call `GlobalPlanner.plan`).
"""
