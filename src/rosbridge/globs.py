"""The topics_glob / services_glob / params_glob filters of rosbridge_websocket.launch.

A launch arg holds a list of fnmatch patterns written like the reference accepts them:
"[/turtle1/*, /rosout]", "['*']", "/turtle1/*" (a single pattern without brackets). Items are separated by
commas, surrounding spaces and quotes are dropped. A YAML list (when the param is set with rosparam) works too.

An empty value ("", "[]", "[ ]", None) means "no filter": everything is allowed. This is what the reference
does with an empty list, and it is the launch default. To hide everything, give a pattern that matches
nothing, e.g. "[none]"."""

import fnmatch


def parse_globs(text):
    """The list of patterns in `text`, or None when it names none (everything allowed)."""
    if text is None:
        return None
    if isinstance(text, (list, tuple)):
        items = [str(item) for item in text]
    elif isinstance(text, str):
        body = text.strip()
        if body.startswith("[") and body.endswith("]"):
            body = body[1:-1]
        items = body.split(",")
    else:
        raise ValueError(f'glob list must be a string like "[/a/*, /b]", got {text!r}')
    patterns = [item.strip().strip("'\"").strip() for item in items]
    patterns = [p for p in patterns if p]
    return patterns or None


def allowed(name, patterns):
    """Whether `name` matches one of `patterns` (fnmatch, case-sensitive); None allows every name."""
    if patterns is None:
        return True
    return any(fnmatch.fnmatchcase(name, pattern) for pattern in patterns)


def filter_names(names, patterns):
    """The names that `patterns` allow, in their original order."""
    return [name for name in names if allowed(name, patterns)]


class Globs:
    """The three filters of one bridge: topics, services and params pattern lists (None = all allowed)."""

    def __init__(self, topics=None, services=None, params=None):
        self.topics, self.services, self.params = topics, services, params

    @classmethod
    def parse(cls, topics_glob="", services_glob="", params_glob=""):
        """From the launch args' text, e.g. Globs.parse(topics_glob="[/turtle1/*]")."""
        return cls(parse_globs(topics_glob), parse_globs(services_glob), parse_globs(params_glob))

    def __repr__(self):
        return f"Globs(topics={self.topics!r}, services={self.services!r}, params={self.params!r})"
